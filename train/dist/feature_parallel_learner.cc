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
  const uint8_t* at() const { return at_; }
  size_t left() const { return static_cast<size_t>(end_ - at_); }

 private:
  const uint8_t* at_;
  const uint8_t* end_;
};

}  // namespace

FeatureParallelLearner::FeatureParallelLearner(Collectives& comm, const FeatureMatrix& features, const TrainingSet& set,
                                               const BoostOptions& options)
    : SerialStumpLearner(features, set, options, comm) {
  const int R = comm.size();
  const std::vector<int32_t> own = rank_dims(features.num_dims, comm.rank(), R);
  for (int32_t d : own) {
    LMB_CHECK(columns().stored(d), "distributed learner: rank " << comm.rank() << " of " << R << " owns dim " << d
                                                                << " but its feature matrix lacks it");
  }
  // Every dim's screening kind, from its owner (one byte a dim, once): what lets every rank
  // compute the same screening plan each round.
  std::vector<uint8_t> mine;
  mine.reserve(own.size());
  for (int32_t d : own) mine.push_back(columns().kind(d));
  std::vector<int64_t> offsets;
  const std::vector<uint8_t> all = comm.allgather_bytes(mine, &offsets);
  kind_.assign(static_cast<size_t>(features.num_dims), 0);
  for (int r = 0; r < R; ++r) {
    const std::vector<int32_t> dims = rank_dims(features.num_dims, r, R);
    LMB_CHECK(offsets[r + 1] - offsets[r] == static_cast<int64_t>(dims.size()),
              "distributed learner: rank " << r << " sent " << offsets[r + 1] - offsets[r] << " screening kinds for "
                                           << dims.size() << " dims");
    for (size_t i = 0; i < dims.size(); ++i) kind_[dims[i]] = all[offsets[r] + static_cast<int64_t>(i)];
  }
}

void FeatureParallelLearner::move_columns(const std::vector<ColumnMove>& moves) {
  // In list order, which every rank walks the same way: no cycle of blocked sends.
  for (size_t i = 0; i < moves.size(); ++i) {
    const ColumnMove& m = moves[i];
    const int tag = static_cast<int>(i);
    if (comm_.rank() == m.from) {
      const std::vector<uint8_t> packed = columns().pack(m.dim);
      comm_.send_bytes(packed.data(), static_cast<int64_t>(packed.size()), m.to, tag);
    } else if (comm_.rank() == m.to) {
      columns().lend(m.dim, comm_.recv_bytes(m.from, tag));
    }
  }
}

std::vector<int32_t> FeatureParallelLearner::choose_dims(int32_t round, const std::vector<int32_t>& round_dims) {
  screening_ = plan_screening(round_dims, kind_, comm_.size());
  move_columns(screening_.moves);
  std::vector<int32_t> mine;
  for (const auto& [d, r] : screening_.screener) {
    if (r == comm_.rank()) mine.push_back(d);
  }
  for (int32_t d : mine) {
    LMB_CHECK(columns().find(d).column, "distributed learner: dim " << d << " of round " << round << " is not here");
  }
  return mine;
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
  while (r.left() > 0) {
    ScreenedCandidate c;
    c.gain = r.get<double>();
    c.dim = r.get<int32_t>();
    c.theta = r.get<int32_t>();
    c.above_fraction = r.get<float>();
    global.push_back(c);
  }
  global = SerialStumpLearner::select_for_refinement(std::move(global));
  const RefinementPlan plan = plan_refinement(global, screening_, comm_.size());
  move_columns(plan.moves);
  std::vector<ScreenedCandidate> mine;
  for (const ScreenedCandidate& c : global) {
    const auto it = std::lower_bound(plan.refiner.begin(), plan.refiner.end(), std::make_pair(c.dim, 0));
    if (it->second == comm_.rank()) mine.push_back(c);
  }
  return mine;
}

StumpRecord FeatureParallelLearner::reduce_best(StumpRecord local, std::vector<uint8_t>* above) {
  if (!comm_.distributed()) return SerialStumpLearner::reduce_best(std::move(local), above);
  // 1. Every rank's (gain, dim, theta): 16 bytes each; all ranks pick the same winner.
  ByteWriter head;
  head.put(local.gain);
  head.put(local.dim);
  head.put(local.theta);
  std::vector<int64_t> offsets;
  const std::vector<uint8_t> heads = comm_.allgather_bytes(head.bytes, &offsets);
  StumpRecord best;
  int winner = -1;
  for (int r = 0; r < comm_.size(); ++r) {
    ByteReader in(heads.data() + offsets[r], heads.data() + offsets[r + 1]);
    StumpRecord h;
    h.gain = in.get<double>();
    h.dim = in.get<int32_t>();
    h.theta = in.get<int32_t>();
    if (h.valid() && stump_better(h, best)) {
      best = h;
      winner = r;
    }
  }
  if (winner < 0) return SerialStumpLearner::reduce_best(StumpRecord{}, above);
  // 2. The winner, which refined the dim and so has its column, broadcasts its sums, the stump's
  //    above bits and the sharing set.
  const size_t S = static_cast<size_t>(features_.num_samples), bit_bytes = (S + 7) / 8;
  ByteWriter w;
  if (comm_.rank() == winner) {
    local = SerialStumpLearner::reduce_best(std::move(local), above);
    for (int64_t v : {local.wp, local.yp, local.wm, local.ym}) w.put(v);
    std::vector<uint8_t> bits(bit_bytes, 0);
    for (size_t s = 0; s < S; ++s) bits[s >> 3] |= static_cast<uint8_t>((*above)[s] << (s & 7));
    w.bytes.insert(w.bytes.end(), bits.begin(), bits.end());
    for (int32_t c : local.classes) w.put(c);
  }
  comm_.broadcast_bytes(&w.bytes, winner);
  if (comm_.rank() == winner) return local;
  ByteReader in(w.bytes.data(), w.bytes.data() + w.bytes.size());
  best.wp = in.get<int64_t>();
  best.yp = in.get<int64_t>();
  best.wm = in.get<int64_t>();
  best.ym = in.get<int64_t>();
  LMB_CHECK(in.left() >= bit_bytes && (in.left() - bit_bytes) % 4 == 0,
            "distributed learner: rank " << winner << " sent a torn record");
  above->resize(S);
  for (size_t s = 0; s < S; ++s) (*above)[s] = (in.at()[s >> 3] >> (s & 7)) & 1;
  ByteReader set(in.at() + bit_bytes, w.bytes.data() + w.bytes.size());
  best.classes.resize(set.left() / 4);
  for (int32_t& c : best.classes) c = set.get<int32_t>();
  return best;
}

}  // namespace lmb
