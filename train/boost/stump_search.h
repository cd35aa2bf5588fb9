// The search of one round: screen the round's dims (train/boost/column_screener.h), pick the
// candidates for refinement (a hook: the serial learner keeps its refine_top best, a distributed
// layer picks globally and spreads them over the ranks), then the full sharing-set search
// (train/boost/sharing_set.h) on every picked (dim, threshold). With refine_top = 0 the full
// search runs on every threshold of every dim (the exact mode of the tests).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "train/boost/boost_options.h"
#include "train/boost/column_screener.h"
#include "train/boost/entry_store.h"
#include "train/boost/feature_columns.h"
#include "train/boost/sharing_set.h"
#include "train/boost/stump_record.h"

namespace lmb {

class StumpSearch {
 public:
  // Candidates in, the ones to refine here out.
  using Select = std::function<std::vector<ScreenedCandidate>(std::vector<ScreenedCandidate>)>;
  // Every argument must outlive this.
  StumpSearch(const FeatureColumns& columns, const EntryStore& entries, const BoostOptions& options);

  // The best stump over `dims` (each stored or lent here) with the entries' current fixed-point
  // weights; invalid when no stump gains. Adds the time of the column passes to *pass_seconds.
  StumpRecord run(const std::vector<int32_t>& dims, const Select& select, double* pass_seconds);
  // The screening alone: every (dim, theta) of `dims` with a positive screening gain, by dim.
  std::vector<ScreenedCandidate> screen(std::vector<int32_t> dims);

 private:
  // The full search on threshold t of the column whose sums the screener collected last.
  StumpRecord refine(int32_t dim, int32_t t, int32_t theta);
  // The search input of threshold t: the touched classes with weight above it.
  SharingInput threshold_input(int32_t t);

  const FeatureColumns& columns_;
  const EntryStore& entries_;
  const BoostOptions& options_;
  ColumnScreener screener_;
  std::vector<int64_t> wp_, yp_, wm_, ym_;
  std::vector<double> q_;
  std::vector<int32_t> active_;  // class of each search row
  std::vector<uint8_t> sharing_scratch_;
};

}  // namespace lmb
