// The feature columns a learner reads: the binned columns this process stores, each with its
// candidate thresholds, and columns of other dims lent to it for one round by a distributed layer
// (pack on the rank that has the column, lend on the other).
#pragma once

#include <cstdint>
#include <vector>

#include "train/boost/boost_options.h"
#include "train/features/feature_matrix.h"

namespace lmb {

class FeatureColumns {
 public:
  struct Layout {
    std::vector<uint8_t> thresholds;  // ascending candidate thresholds
    uint8_t bucket[256];              // bucket of a bin: number of thresholds below it
    float above_fraction = 0.f;       // samples above the smallest threshold
  };
  // A dim's column (S bins) and layout, stored or lent; column nullptr: neither.
  struct Ref {
    int32_t dim = -1;
    const uint8_t* column = nullptr;
    const Layout* layout = nullptr;
  };
  // How a dim is screened (ColumnScreener): never (a constant column), in the blocked class-major
  // pass (at most kMaxBlockedThresholds thresholds, blocked screening on, no step), or by a column
  // pass of its own.
  enum Kind : uint8_t { kConstant = 0, kBlocked = 1, kColumnPass = 2 };
  static constexpr int kMaxBlockedThresholds = 15;  // 4-bit buckets

  // `features` must outlive this. Throws lmb::Error when every stored column is constant.
  FeatureColumns(const FeatureMatrix& features, const ScreeningOptions& options);

  int64_t num_samples() const { return features_.num_samples; }
  int32_t num_dims() const { return features_.num_dims; }
  bool stored(int32_t dim) const { return stored_index(dim) >= 0; }
  Ref find(int32_t dim) const;
  // find(dim), or lmb::Error naming `what` when the dim is neither stored nor lent here.
  Ref get(int32_t dim, const char* what) const;
  Kind kind(const Layout& layout) const;
  Kind kind(int32_t dim) const { return kind(*get(dim, "screening kind").layout); }
  // above[s] = [v_dim(s) > theta] for every sample, from the column here.
  void above(int32_t dim, int32_t theta, std::vector<uint8_t>* above) const;

  // The column of `dim` (stored or lent here) as bytes for another rank: S bins, the above
  // fraction, the thresholds and their count. Throws lmb::Error when it is not here.
  std::vector<uint8_t> pack(int32_t dim) const;
  // Makes a packed column usable here until drop_lent(); nothing when the dim is here already.
  // Throws lmb::Error on a packed column of the wrong size or with unordered thresholds.
  void lend(int32_t dim, std::vector<uint8_t> packed);
  void drop_lent() { lent_.clear(); }

 private:
  int32_t stored_index(int32_t dim) const {
    return dim >= 0 && dim < static_cast<int32_t>(global_to_stored_.size()) ? global_to_stored_[dim] : -1;
  }
  Layout make_layout(const uint8_t* column) const;
  static void fill_buckets(Layout* layout);

  struct Lent {
    int32_t dim;
    std::vector<uint8_t> column;
    Layout layout;
  };
  const FeatureMatrix& features_;
  ScreeningOptions options_;
  std::vector<int32_t> global_to_stored_;
  std::vector<Layout> layouts_;  // per stored column
  std::vector<Lent> lent_;
};

}  // namespace lmb
