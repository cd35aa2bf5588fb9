// The learner's entries: per class its positives and negatives (the paper's L+_c and L-_c), as
// (sample, class, z = +1 / -1, weight), with the round's fixed-point weights and class totals.
//
// Weights are doubles, true weight = stored * 2^weight_exponent (rescaled by exact powers of two to
// stay near 1). Each round quantize() turns them into int64 fixed point with a power-of-two scale
// chosen from the largest weight and the entry count, so that any sum of entries is an integer
// below 2^52: every histogram and set sum is then exact in int64 and in double, whatever the
// summation order, which is what makes the screening kernels and the ranks agree bit for bit.
//
// Two copies: sample-major (the column passes and the weight update walk a sample's entries) and
// class-major, positives then negatives of each class by ascending sample (the blocked screening
// streams a class's entries).
#pragma once

#include <cstdint>
#include <vector>

#include "train/boost/learner_state.h"

namespace lmb {

class EntryStore {
 public:
  // What the column passes read of an entry, packed so that a sample's entries share cache lines.
  struct HotEntry {
    int64_t wq;    // this round's fixed-point weight
    int32_t code;  // class * 2 + (z < 0)
    int32_t unused;
  };
  // One entry with its true weight (tests, checkpoints).
  struct Entry {
    int64_t sample = 0;
    int32_t cls = 0;
    int8_t z = 1;
    double weight = 0.0;
  };

  EntryStore(int64_t num_samples, int32_t num_classes_with_background);

  // Replaces every entry (samples < num_samples, codes = class * 2 + (z < 0), stored weights);
  // any order, sorted here by (sample, code); a sorted prefix followed by a few more is merged.
  void assign(const std::vector<int64_t>& samples, const std::vector<int32_t>& codes,
              const std::vector<double>& weights, int weight_exponent);
  // Adds entries (stored weights relative to the current exponent).
  void append(const std::vector<int64_t>& samples, const std::vector<int32_t>& codes,
              const std::vector<double>& weights);

  // This round's fixed point and class totals W_c, Y_c, q_c = Y_c^2 / W_c. Throws lmb::Error when a
  // weight is not finite or all are zero (`round` names the round).
  void quantize(int32_t round);

  // w <- w exp(-z h) for the round's stump: h = alpha (above) / beta (below) for the classes with
  // in_set[c], k[c] for the others. Returns, in true weight units, the squared error
  // sum w (z - h)^2 of the fit (weights before the update) and the cost sum w after it.
  struct UpdateSums {
    double squared_error = 0.0;
    double cost = 0.0;
  };
  UpdateSums update(const std::vector<uint8_t>& above, const std::vector<uint8_t>& in_set, double alpha, double beta,
                    const std::vector<double>& k);

  int64_t num_samples() const { return num_samples_; }
  int32_t num_classes() const { return C1_; }  // background included
  int64_t size() const { return static_cast<int64_t>(code_.size()); }
  int weight_exponent() const { return weight_exponent_; }
  int quant_shift() const { return quant_shift_; }  // fixed point units = stored weight * 2^quant_shift
  double exp_loss() const;                          // sum of true weights
  std::vector<Entry> entries() const;               // sample-major
  // Sample-major: sample s's entries are [sample_begin()[s], sample_begin()[s + 1]).
  const int64_t* sample_begin() const { return sample_offset_.data(); }
  const HotEntry* hot() const { return hot_.data(); }
  int32_t code(int64_t e) const { return code_[e]; }
  double stored_weight(int64_t e) const { return weight_[e]; }
  // Class-major: class c's entries are [class_begin(c), class_begin(c + 1)), its negatives from
  // class_negatives_begin(c); class_sample() has 32 samples of padding after the last entry (a
  // prefetch distance).
  int64_t class_begin(int32_t c) const { return class_begin_[c]; }
  int64_t class_negatives_begin(int32_t c) const { return class_neg_begin_[c]; }
  const int32_t* class_sample() const { return class_sample_.data(); }
  const int64_t* class_wq() const { return class_wq_.data(); }
  // This round's class totals.
  const std::vector<int64_t>& class_w() const { return class_w_; }
  const std::vector<int64_t>& class_y() const { return class_y_; }
  const std::vector<double>& class_q() const { return class_q_; }

  void save(LearnerState* state) const;  // entries and exponent
  // Throws lmb::Error naming the first entry out of range or order.
  void check(const LearnerState& state) const;
  void restore(const LearnerState& state);  // after check()

 private:
  void build_class_major();

  int64_t num_samples_ = 0;
  int32_t C1_ = 0;
  std::vector<int64_t> sample_offset_;  // size num_samples + 1
  std::vector<int32_t> code_;           // class * 2 + (z < 0)
  std::vector<double> weight_;          // stored weights
  std::vector<HotEntry> hot_;
  std::vector<int64_t> class_begin_, class_neg_begin_;
  std::vector<int64_t> class_index_;  // where sample-major entry e sits in the class-major copy
  std::vector<int32_t> class_sample_;
  std::vector<int64_t> class_wq_;
  int weight_exponent_ = 0;
  int quant_shift_ = 0;
  std::vector<int64_t> class_w_, class_y_;
  std::vector<double> class_q_;
};

}  // namespace lmb
