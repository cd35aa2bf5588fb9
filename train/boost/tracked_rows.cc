#include "train/boost/tracked_rows.h"

#include <algorithm>
#include <cstring>
#include <limits>

#include "common/cpu_dispatch.h"
#include "common/error.h"
#include "common/random.h"

namespace lmb {

namespace {

constexpr uint64_t kValidationTag = 0x56414C4944415445ull;
constexpr uint64_t kPoolTag = 0x504F4F4C53414D50ull;

// Samples chosen by a seeded hash order, at most `cap`, returned ascending.
std::vector<int64_t> hash_subset(const std::vector<int64_t>& samples, int64_t cap, uint64_t seed, uint64_t tag) {
  if (static_cast<int64_t>(samples.size()) <= cap) return samples;
  std::vector<std::pair<uint64_t, int64_t>> keyed;
  keyed.reserve(samples.size());
  for (int64_t s : samples) keyed.emplace_back(counter_hash(seed, tag, static_cast<uint64_t>(s)), s);
  std::nth_element(keyed.begin(), keyed.begin() + cap, keyed.end());
  std::vector<int64_t> out;
  for (int64_t i = 0; i < cap; ++i) out.push_back(keyed[i].second);
  std::sort(out.begin(), out.end());
  return out;
}

// The first c in [0, n) with the largest offset[c] + row[c] (finite doubles), and that score: the
// maximum four lanes at a time, then the first class that reaches it (the same double sums, so
// the equality is exact).
LMB_CLONES_AVX2 int32_t first_max_score(const double* offset, const float* row, int32_t n, double* best) {
  using V4 = double __attribute__((vector_size(32)));
  using F4 = float __attribute__((vector_size(16)));
  double m = -std::numeric_limits<double>::infinity();
  int32_t c = 0;
  if (n >= 4) {
    V4 vm = {m, m, m, m};
    for (; c + 4 <= n; c += 4) {
      V4 o;
      F4 f;
      std::memcpy(&o, offset + c, sizeof(o));
      std::memcpy(&f, row + c, sizeof(f));
      const V4 s = o + __builtin_convertvector(f, V4);
      vm = s > vm ? s : vm;
    }
    m = std::max(std::max(vm[0], vm[1]), std::max(vm[2], vm[3]));
  }
  for (; c < n; ++c) m = std::max(m, offset[c] + static_cast<double>(row[c]));
  for (c = 0; c < n; ++c) {
    if (offset[c] + static_cast<double>(row[c]) == m) break;
  }
  *best = m;
  return c;
}

}  // namespace

TrackedRows::TrackedRows(const TrainingSet& set, Collectives& comm)
    : set_(set), comm_(comm), C1_(set.num_classes_with_background()) {
  class_offset_.assign(static_cast<size_t>(C1_), 0.0);
}

void TrackedRows::select(const BoostOptions& options) {
  std::vector<int64_t> validation, train;
  for (int64_t s = 0; s < set_.num_samples(); ++s) {
    if (set_.sample_is_validation[s]) {
      if (set_.sample_class[s] < set_.num_classes) validation.push_back(s);
    } else {
      train.push_back(s);
    }
  }
  samples_ = options.validation.interval > 0
                 ? hash_subset(validation, options.validation.max_samples, options.seed, kValidationTag)
                 : std::vector<int64_t>{};
  num_validation_rows_ = static_cast<int64_t>(samples_.size());
  if (options.mining.interval > 0) {
    const auto pool = hash_subset(train, options.mining.pool_size, options.seed, kPoolTag);
    samples_.insert(samples_.end(), pool.begin(), pool.end());
  }
  split();
  scores_.assign(static_cast<size_t>(local_rows()) * static_cast<size_t>(C1_), 0.f);
  pending_pool_.clear();
}

void TrackedRows::split() {
  part_ = comm_.rank();
  parts_ = comm_.size();
  LMB_CHECK(parts_ >= 1 && part_ >= 0 && part_ < parts_, "boost: work part " << part_ << " of " << parts_);
}

int64_t TrackedRows::local_rows() const {
  const int64_t n = static_cast<int64_t>(samples_.size());
  return n > part_ ? (n - part_ + parts_ - 1) / parts_ : 0;
}

int64_t TrackedRows::local_validation_rows() const {
  const int64_t n = num_validation_rows_;
  return n > part_ ? (n - part_ + parts_ - 1) / parts_ : 0;
}

void TrackedRows::add_stump(const std::vector<int32_t>& classes, std::vector<float> d_above, std::vector<float> d_below,
                            const std::vector<uint8_t>& above) {
  const size_t n = classes.size();
  const int64_t v = local_validation_rows(), rows = local_rows();
  auto row_above = [&](int64_t i) { return above[samples_[part_ + i * parts_]]; };
  if (n * 4 > static_cast<size_t>(C1_)) {
    // A large sharing set: add dense rows of changes (0 outside S, and x + 0.0f == x for the
    // scores, which are never -0), a vectorised stream instead of scattered adds.
    std::vector<float> dense[2] = {std::vector<float>(static_cast<size_t>(C1_), 0.f),
                                   std::vector<float>(static_cast<size_t>(C1_), 0.f)};
    for (size_t j = 0; j < n; ++j) {
      dense[0][classes[j]] = d_below[j];
      dense[1][classes[j]] = d_above[j];
    }
    for (int64_t i = 0; i < v; ++i) {
      float* row = scores_.data() + static_cast<size_t>(i) * C1_;
      const float* d = dense[row_above(i)].data();
      for (int32_t c = 0; c < C1_; ++c) row[c] += d[c];
    }
  } else {
    for (int64_t i = 0; i < v; ++i) {
      float* row = scores_.data() + static_cast<size_t>(i) * C1_;
      const float* d = row_above(i) ? d_above.data() : d_below.data();
      for (size_t j = 0; j < n; ++j) row[classes[j]] += d[j];
    }
  }
  if (rows > v) {
    PendingStump p;
    p.classes = classes;
    p.above.resize(static_cast<size_t>(rows - v));
    for (int64_t i = v; i < rows; ++i) p.above[i - v] = row_above(i);
    p.d_above = std::move(d_above);
    p.d_below = std::move(d_below);
    pending_pool_.push_back(std::move(p));
  }
}

void TrackedRows::add_constants(const std::vector<double>& k) {
  for (int32_t c = 0; c < C1_; ++c) class_offset_[c] += k[c];
}

void TrackedRows::flush_pool() {
  // In round order, the same float additions as one round at a time.
  const int64_t v = local_validation_rows(), rows = local_rows();
  if (!pending_pool_.empty()) {
    for (int64_t i = v; i < rows; ++i) {
      float* row = scores_.data() + static_cast<size_t>(i) * C1_;
      for (const PendingStump& p : pending_pool_) {
        const float* d = p.above[i - v] ? p.d_above.data() : p.d_below.data();
        const size_t n = p.classes.size();
        for (size_t j = 0; j < n; ++j) row[p.classes[j]] += d[j];
      }
    }
  }
  pending_pool_.clear();
}

void TrackedRows::count_validation_hits(int64_t* all, int64_t* landmarks) const {
  // A row's best landmark class is the first maximum over the landmark classes; the background
  // class then wins the row only if it scores strictly higher (the first maximum over all
  // classes, as it comes last).
  const int32_t C = C1_ - 1;
  *all = *landmarks = 0;
  for (int64_t r = part_, i = 0; r < num_validation_rows_; r += parts_, ++i) {
    const float* row = scores_.data() + static_cast<size_t>(i) * C1_;
    double best_score = 0.0;
    const int32_t best = first_max_score(class_offset_.data(), row, C, &best_score);
    const int32_t truth = set_.sample_class[samples_[r]];
    *landmarks += best == truth;
    *all += best == truth && !(class_offset_[C] + row[C] > best_score);
  }
}

void TrackedRows::validation_precision(double* all, double* landmarks) {
  if (num_validation_rows_ == 0) {
    *all = *landmarks = -1.0;
    return;
  }
  int64_t hits_all = 0, hits_landmarks = 0;
  count_validation_hits(&hits_all, &hits_landmarks);
  hits_all = comm_.allreduce_sum(hits_all);
  hits_landmarks = comm_.allreduce_sum(hits_landmarks);
  const double n = static_cast<double>(num_validation_rows_);
  *all = static_cast<double>(hits_all) / n;
  *landmarks = static_cast<double>(hits_landmarks) / n;
}

void TrackedRows::save(LearnerState* st) {
  st->tracked_samples = samples_;
  st->num_validation_rows = num_validation_rows_;
  st->class_offset = class_offset_;
  // Every rank's rows, gathered to rank 0 and put back in global row order: rank p's local row i
  // is global row p + i * parts.
  flush_pool();
  const size_t N = samples_.size();
  st->tracked_scores.clear();
  if (part_ == 0) st->tracked_scores.resize(N * static_cast<size_t>(C1_));
  const auto* mine = reinterpret_cast<const uint8_t*>(scores_.data());
  comm_.gather_bytes(
      mine, static_cast<int64_t>(scores_.size() * sizeof(float)), 0, [&](int p, const uint8_t* bytes, int64_t size) {
        const size_t row_bytes = static_cast<size_t>(C1_) * sizeof(float);
        const size_t rows = N > static_cast<size_t>(p) ? (N - p + parts_ - 1) / parts_ : 0;
        LMB_CHECK(static_cast<size_t>(size) == rows * row_bytes,
                  "boost: part " << p << " sent " << size << " bytes of tracked scores for " << rows << " rows x "
                                 << C1_ << " classes");
        for (size_t i = 0; i < rows; ++i) {
          std::memcpy(st->tracked_scores.data() + (p + i * parts_) * C1_, bytes + i * row_bytes, row_bytes);
        }
      });
}

void TrackedRows::check(const LearnerState& st) const {
  const int64_t S = set_.num_samples();
  LMB_CHECK(static_cast<int64_t>(st.class_offset.size()) == C1_,
            "learner state: " << st.class_offset.size() << " class offsets for " << C1_ << " classes");
  LMB_CHECK(st.num_validation_rows >= 0 && st.num_validation_rows <= static_cast<int64_t>(st.tracked_samples.size()),
            "learner state: " << st.num_validation_rows << " validation rows of " << st.tracked_samples.size());
  for (int64_t s : st.tracked_samples) {
    LMB_CHECK(s >= 0 && s < S, "learner state: tracked sample " << s << " of " << S);
  }
  LMB_CHECK(st.tracked_scores.size() == st.tracked_samples.size() * static_cast<size_t>(C1_),
            "learner state: " << st.tracked_scores.size() << " tracked scores for " << st.tracked_samples.size()
                              << " rows x " << C1_ << " classes");
}

void TrackedRows::restore(const LearnerState& st) {
  samples_ = st.tracked_samples;
  num_validation_rows_ = st.num_validation_rows;
  split();
  pending_pool_.clear();
  scores_.resize(static_cast<size_t>(local_rows()) * C1_);
  for (int64_t i = 0; i < local_rows(); ++i) {
    const float* row = st.tracked_scores.data() + static_cast<size_t>(part_ + i * parts_) * C1_;
    std::copy(row, row + C1_, scores_.data() + static_cast<size_t>(i) * C1_);
  }
  class_offset_ = st.class_offset;
}

}  // namespace lmb
