// Per-(class, threshold) weight sums of feature columns over the learner's entries, and the
// screening gains (train/boost/screening_gain.h) that rank every (dim, threshold) of a round.
//
// Two ways to the same sums, bit for bit (column_screener_test):
// - a column pass: the samples above the column's smallest threshold (SSE2, 16 bins at a time),
//   then their entries' weights scattered into a (bucket, class) histogram, sample-major; any
//   number of thresholds, and the histogram also feeds the full search (collect_sums);
// - the blocked pass: kBlockDims columns of at most 15 thresholds at once, streaming the entries
//   class-major and reading each sample's 4-bit buckets of the block's columns from one packed
//   word, the per-class buckets in L1; then the kernel on four thresholds per SIMD lane.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "train/boost/entry_store.h"
#include "train/boost/feature_columns.h"
#include "train/boost/stump_record.h"

namespace lmb {

class ColumnScreener {
 public:
  static constexpr int kBlockDims = 8;  // columns per blocked pass

  // `entries` must outlive this; it is read as it is at each call (quantized this round).
  explicit ColumnScreener(const EntryStore& entries);

  // Every (dim, theta) of `sorted_dims` (ascending, each stored or lent in `columns`) with a
  // positive screening gain, dims in ascending order; `step`: one alternation step from each
  // class group (column passes only). Adds the time of the histogram passes to *pass_seconds.
  std::vector<ScreenedCandidate> screen(const FeatureColumns& columns, const std::vector<int32_t>& sorted_dims,
                                        bool step, double* pass_seconds);
  // The screening gains of one column by a column pass: gains[t] per candidate threshold.
  void screen_column(const FeatureColumns::Ref& ref, bool step, std::vector<double>* gains);
  // The screening gains of up to kBlockDims columns (each with 1..15 thresholds) in one blocked
  // pass: gains[k * 16 + t].
  void screen_block(const FeatureColumns::Ref* refs, int32_t count, double* gains);

  // The sums of one column for the full search: the classes with weight above the smallest
  // threshold (ascending), and per threshold t and such class j the positive and negative weight
  // above t, at [t * touched().size() + j].
  void collect_sums(const FeatureColumns::Ref& ref);
  const std::vector<int32_t>& touched() const { return touched_; }
  const std::vector<int64_t>& positive_above() const { return cum_p_; }
  const std::vector<int64_t>& negative_above() const { return cum_n_; }

 private:
  // Per (class, bucket) sums of one column into hist_ (sample-major).
  void scatter(const FeatureColumns::Ref& ref);
  // scatter(), then bucket t becomes the sums above threshold t; returns the thresholds.
  int32_t histogram(const FeatureColumns::Ref& ref);
  void clear_histogram(int32_t num_thresholds);  // back to all zero

  const EntryStore& entries_;
  std::vector<int64_t> hist_;                         // ((bucket - 1) * C1 + class) * 2 + neg; all zero between passes
  std::vector<std::pair<int32_t, int32_t>> nonzero_;  // (sample, bucket) of a column pass
  std::vector<uint32_t> packed_buckets_;              // per sample: bucket of the block's k-th dim in bits 4k..4k+3
  std::vector<double> gains_;
  std::vector<int32_t> touched_;
  std::vector<int64_t> cum_p_, cum_n_;
};

}  // namespace lmb
