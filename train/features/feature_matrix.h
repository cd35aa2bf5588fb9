// Training features, binned and stored column-major: the learner reads a few hundred random
// columns per round and, within a column, the samples of each class's entry lists.
//
// Feature values are uint8 bins everywhere (training and inference compute the same integers):
//   context dims: round(255 * count_w / count_all) of the region's bag of words (0 for an empty
//                 region), computed in integer arithmetic;
//   descriptor dims: the descriptor bit, 0 or 1.
// A decision stump tests bin > threshold (threshold in 0..254).
#pragma once

#include <cstdint>
#include <vector>

namespace lmb {

struct FeatureMatrix {
  int64_t num_samples = 0;
  int32_t num_dims = 0;
  // Column d holds num_samples bytes at data[d * num_samples]. A matrix may hold only some
  // columns (a rank's share): then `dims` lists the global dimension of each stored column and
  // column i is global dimension dims[i]. Empty `dims` means all columns, in order.
  std::vector<int32_t> dims;
  std::vector<uint8_t> data;

  int32_t num_stored_columns() const { return dims.empty() ? num_dims : static_cast<int32_t>(dims.size()); }
  const uint8_t* column(int32_t stored_index) const {
    return data.data() + static_cast<int64_t>(stored_index) * num_samples;
  }
  uint8_t* column(int32_t stored_index) { return data.data() + static_cast<int64_t>(stored_index) * num_samples; }
};

}  // namespace lmb
