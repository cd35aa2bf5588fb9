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
  if (features.dims.empty()) return;  // every dim stored
  std::vector<uint8_t> stored(static_cast<size_t>(features.num_dims), 0);
  for (int32_t d : features.dims) stored[d] = 1;
  for (int32_t d : rank_dims(features.num_dims, comm.rank(), comm.size())) {
    LMB_CHECK(stored[d], "distributed learner: rank " << comm.rank() << " of " << comm.size()
                                                      << " owns dim " << d << " but its feature matrix lacks it");
  }
}

std::vector<int32_t> FeatureParallelLearner::choose_dims(int32_t round, const std::vector<int32_t>& round_dims) {
  std::vector<int32_t> mine;
  for (int32_t d : round_dims) {
    if (owner(d) == comm_.rank()) mine.push_back(d);
  }
  return SerialStumpLearner::choose_dims(round, mine);
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
    global.push_back(c);
  }
  global = SerialStumpLearner::select_for_refinement(std::move(global));
  std::vector<ScreenedCandidate> mine;
  for (const ScreenedCandidate& c : global) {
    if (owner(c.dim) == comm_.rank()) mine.push_back(c);
  }
  return mine;
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
