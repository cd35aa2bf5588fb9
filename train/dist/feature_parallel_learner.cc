#include "train/dist/feature_parallel_learner.h"

#include <algorithm>
#include <cstring>

#include "common/error.h"

namespace lmb {

namespace {

// Flat little records for the gathers (all ranks run the same binary on the same machine type).
class ByteWriter {
 public:
  template <class T>
  void put(const T& v) {
    const auto* p = reinterpret_cast<const uint8_t*>(&v);
    bytes.insert(bytes.end(), p, p + sizeof(T));
  }
  std::vector<uint8_t> bytes;
};

class ByteReader {
 public:
  ByteReader(const uint8_t* begin, const uint8_t* end) : at_(begin), end_(end) {}
  template <class T>
  T get() {
    LMB_CHECK(at_ + sizeof(T) <= end_, "distributed learner: a gathered record is truncated");
    T v;
    std::memcpy(&v, at_, sizeof(T));
    at_ += sizeof(T);
    return v;
  }
  bool done() const { return at_ == end_; }

 private:
  const uint8_t* at_;
  const uint8_t* end_;
};

}  // namespace

std::vector<int32_t> rank_dims(int32_t num_dims, int rank, int size) {
  LMB_CHECK(size >= 1 && rank >= 0 && rank < size, "rank_dims: rank " << rank << " of " << size);
  std::vector<int32_t> dims;
  for (int32_t d = rank; d < num_dims; d += size) dims.push_back(d);
  return dims;
}

FeatureParallelLearner::FeatureParallelLearner(Communicator& comm, const FeatureMatrix& features,
                                               const TrainingSet& set, const BoostOptions& options)
    : SerialStumpLearner(features, set, options), comm_(comm) {
  const std::vector<int32_t> own = rank_dims(features.num_dims, comm.rank(), comm.size());
  if (!features.dims.empty()) {
    std::vector<uint8_t> stored(static_cast<size_t>(features.num_dims), 0);
    for (int32_t d : features.dims) stored[d] = 1;
    for (int32_t d : own) {
      LMB_CHECK(stored[d], "distributed learner: rank " << comm.rank() << " of " << comm.size()
                                                        << " owns dim " << d << " but its feature matrix lacks it");
    }
  }
  // Every dim's screening kind, from its owner (one byte a dim, once): what lets every rank
  // compute the same balanced screening assignment each round.
  std::vector<uint8_t> mine;
  mine.reserve(own.size());
  for (int32_t d : own) mine.push_back(static_cast<uint8_t>(screening_kind(d)));
  std::vector<int64_t> offsets;
  const std::vector<uint8_t> all = comm_.allgather_bytes(mine, &offsets);
  kind_.assign(static_cast<size_t>(features.num_dims), 0);
  for (int r = 0; r < comm.size(); ++r) {
    const std::vector<int32_t> dims = rank_dims(features.num_dims, r, comm.size());
    LMB_CHECK(offsets[r + 1] - offsets[r] == static_cast<int64_t>(dims.size()),
              "distributed learner: rank " << r << " sent " << offsets[r + 1] - offsets[r] << " screening kinds for "
                                           << dims.size() << " dims");
    for (size_t i = 0; i < dims.size(); ++i) kind_[dims[i]] = all[offsets[r] + static_cast<int64_t>(i)];
  }
}

void FeatureParallelLearner::move_columns(const std::vector<Move>& moves) {
  // In list order, which every rank walks the same way: no cycle of blocked sends.
  for (size_t i = 0; i < moves.size(); ++i) {
    const Move& m = moves[i];
    const int tag = static_cast<int>(i);
    if (comm_.rank() == m.from) {
      const std::vector<uint8_t> packed = pack_column(m.dim);
      comm_.send_bytes(packed.data(), static_cast<int64_t>(packed.size()), m.to, tag);
    } else if (comm_.rank() == m.to) {
      lend_column(m.dim, comm_.recv_bytes(m.from, tag));
    }
  }
}

std::vector<int32_t> FeatureParallelLearner::choose_dims(int32_t round, const std::vector<int32_t>& round_dims) {
  const int R = comm_.size();
  screener_.clear();
  for (int32_t d : round_dims) screener_.emplace_back(d, owner(d));
  if (R > 1) {
    // The blocked screening costs one class-major pass per kBlockDims dims: a rank's cost is
    // ceil(n / 8) passes for its n blocked dims. Ranks above the least possible maximum,
    // 8 ceil(ceil(N / 8) / R) dims, lend their highest dims to the ranks below it.
    constexpr int64_t kBlock = 8;
    std::vector<std::vector<int32_t>> blocked(static_cast<size_t>(R));
    int64_t total = 0;
    for (int32_t d : round_dims) {
      if (kind_[d] == 1) {
        blocked[owner(d)].push_back(d);
        ++total;
      }
    }
    const int64_t limit = kBlock * (((total + kBlock - 1) / kBlock + R - 1) / R);
    std::vector<Move> moves;
    int to = 0;
    for (int from = 0; from < R; ++from) {
      while (static_cast<int64_t>(blocked[from].size()) > limit) {
        while (static_cast<int64_t>(blocked[to].size()) >= limit) ++to;  // exists: total <= R * limit
        const int32_t d = blocked[from].back();
        blocked[from].pop_back();
        blocked[to].push_back(d);
        moves.push_back({d, from, to});
      }
    }
    std::sort(moves.begin(), moves.end(), [](const Move& x, const Move& y) { return x.dim < y.dim; });
    move_columns(moves);
    for (const Move& m : moves) {
      for (auto& [d, r] : screener_) {
        if (d == m.dim) r = m.to;
      }
    }
  }
  std::vector<int32_t> mine;
  for (const auto& [d, r] : screener_) {
    if (r == comm_.rank()) mine.push_back(d);
  }
  return SerialStumpLearner::choose_dims(round, mine);
}

int FeatureParallelLearner::screener(int32_t dim) const {
  for (const auto& [d, r] : screener_) {
    if (d == dim) return r;
  }
  return owner(dim);
}

std::vector<ScreenedCandidate> FeatureParallelLearner::select_for_refinement(std::vector<ScreenedCandidate> local) {
  // The global refine_top is among the union of every rank's local refine_top.
  local = SerialStumpLearner::select_for_refinement(std::move(local));
  if (!comm_.distributed()) return local;
  ByteWriter w;
  for (const ScreenedCandidate& c : local) {
    w.put(c.gain);
    w.put(c.dim);
    w.put(c.theta);
    w.put(c.above_fraction);
  }
  std::vector<int64_t> offsets;
  const std::vector<uint8_t> all = comm_.allgather_bytes(w.bytes, &offsets);
  std::vector<ScreenedCandidate> global;
  ByteReader r(all.data(), all.data() + all.size());
  while (!r.done()) {
    ScreenedCandidate c;
    c.gain = r.get<double>();
    c.dim = r.get<int32_t>();
    c.theta = r.get<int32_t>();
    c.above_fraction = r.get<float>();
    global.push_back(c);
  }
  global = SerialStumpLearner::select_for_refinement(std::move(global));

  // Balance the refinement: a candidate dim costs a column pass (its entries above the smallest
  // threshold) plus a sharing-set search per candidate threshold; dims go, most expensive first,
  // to the least loaded rank (the rank that screened it, which has the column, on a tie). Every
  // rank computes the same assignment from the same list.
  struct DimCost {
    int32_t dim;
    double cost;
  };
  std::vector<DimCost> dims;
  for (const ScreenedCandidate& c : global) {
    auto it = std::find_if(dims.begin(), dims.end(), [&](const DimCost& d) { return d.dim == c.dim; });
    if (it == dims.end()) {
      // Measured at paper scale: a column pass costs ~3.3 sharing-set searches per unit of
      // above_fraction.
      dims.push_back({c.dim, 3.3 * c.above_fraction + 1.0});
    } else {
      it->cost += 1.0;
    }
  }
  std::sort(dims.begin(), dims.end(), [](const DimCost& x, const DimCost& y) {
    return x.cost != y.cost ? x.cost > y.cost : x.dim < y.dim;
  });
  std::vector<double> load(static_cast<size_t>(comm_.size()), 0.0);
  std::vector<std::pair<int32_t, int>> assigned;  // (dim, rank)
  std::vector<Move> moves;
  for (const DimCost& d : dims) {
    const int home = screener(d.dim);
    int best = home;
    for (int k = 0; k < comm_.size(); ++k) {
      if (load[k] < load[best]) best = k;
    }
    load[best] += d.cost;
    assigned.emplace_back(d.dim, best);
    if (best != home) moves.push_back({d.dim, home, best});
  }
  // Columns refined away from their screener travel there (S bytes each).
  std::sort(moves.begin(), moves.end(), [](const Move& x, const Move& y) { return x.dim < y.dim; });
  move_columns(moves);
  std::sort(assigned.begin(), assigned.end());
  std::vector<ScreenedCandidate> mine;
  for (const ScreenedCandidate& c : global) {
    const auto it = std::lower_bound(assigned.begin(), assigned.end(), std::make_pair(c.dim, 0));
    if (it->second == comm_.rank()) mine.push_back(c);
  }
  return mine;
}

std::vector<uint8_t> FeatureParallelLearner::gather_parts(const std::vector<uint8_t>& local) {
  std::vector<int64_t> offsets;
  return comm_.allgather_bytes(local, &offsets);
}

void FeatureParallelLearner::gather_parts_to_first(const uint8_t* local, int64_t size,
                                                   const std::function<void(int, const uint8_t*, int64_t)>& take) {
  comm_.gather_bytes(local, size, 0, take);
}

StumpRecord FeatureParallelLearner::reduce_best(StumpRecord local) {
  if (!comm_.distributed()) return local;
  // 1. Every rank's (gain, dim, theta): 16 bytes each; all ranks pick the same winner.
  ByteWriter head;
  head.put(local.gain);
  head.put(local.dim);
  head.put(local.theta);
  std::vector<int64_t> offsets;
  const std::vector<uint8_t> heads = comm_.allgather_bytes(head.bytes, &offsets);
  StumpRecord best_head;
  int winner = -1;
  for (int r = 0; r < comm_.size(); ++r) {
    ByteReader in(heads.data() + offsets[r], heads.data() + offsets[r + 1]);
    StumpRecord h;
    h.gain = in.get<double>();
    h.dim = in.get<int32_t>();
    h.theta = in.get<int32_t>();
    if (h.valid() && stump_better(h, best_head)) {
      best_head = h;
      winner = r;
    }
  }
  if (winner < 0) return StumpRecord{};
  // 2. The winner broadcasts its whole record (sums and sharing set).
  ByteWriter w;
  if (comm_.rank() == winner) {
    w.put(local.wp);
    w.put(local.yp);
    w.put(local.wm);
    w.put(local.ym);
    for (int32_t c : local.classes) w.put(c);
  }
  comm_.broadcast_bytes(&w.bytes, winner);
  if (comm_.rank() == winner) return local;
  StumpRecord rec = best_head;
  ByteReader in(w.bytes.data(), w.bytes.data() + w.bytes.size());
  rec.wp = in.get<int64_t>();
  rec.yp = in.get<int64_t>();
  rec.wm = in.get<int64_t>();
  rec.ym = in.get<int64_t>();
  LMB_CHECK((w.bytes.size() - 32) % 4 == 0, "distributed learner: rank " << winner << " sent a torn record");
  rec.classes.resize((w.bytes.size() - 32) / 4);
  for (int32_t& c : rec.classes) c = in.get<int32_t>();
  return rec;
}

void FeatureParallelLearner::stump_above(int32_t dim, int32_t theta, std::vector<uint8_t>* above) {
  if (!comm_.distributed()) {
    SerialStumpLearner::stump_above(dim, theta, above);
    return;
  }
  const int root = owner(dim);
  const size_t S = static_cast<size_t>(features_.num_samples);
  std::vector<uint8_t> bits((S + 7) / 8, 0);
  if (comm_.rank() == root) {
    SerialStumpLearner::stump_above(dim, theta, above);
    for (size_t s = 0; s < S; ++s) bits[s >> 3] |= static_cast<uint8_t>((*above)[s] << (s & 7));
  }
  comm_.broadcast_bytes(&bits, root);
  if (comm_.rank() != root) {
    above->resize(S);
    for (size_t s = 0; s < S; ++s) (*above)[s] = (bits[s >> 3] >> (s & 7)) & 1;
  }
}

}  // namespace lmb
