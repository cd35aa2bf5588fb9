// Measures the time offset between a sequence's image timestamps and its ground-truth poses from
// the images themselves: the relative rotation of consecutive frames (ORB matches, undistorted,
// essential matrix with RANSAC) is compared with the ground truth's relative rotation looked up at
// the image times + offset, for a range of offsets. A constant rotation rate hides the offset;
// the changing rate of hand-held motion reveals it (the error grows with |offset - true offset|
// times the angular acceleration).
#pragma once

#include <filesystem>
#include <vector>

#include "common/camera.h"
#include "train/import/tum_import.h"

namespace lmb {

struct TimeOffsetScan {
  std::vector<double> offset_s;    // scanned offsets (added to image timestamps), ascending
  std::vector<double> median_deg;  // median relative-rotation disagreement at each offset
  std::vector<int> pairs_used;     // frame pairs with ground truth at that offset
  int pairs = 0;                   // consecutive pairs with a reliable visual rotation
  double best_offset_s = 0.0;      // the offset with the smallest median
};

// Scans offsets from -max_offset_s to +max_offset_s in steps of step_s over the images of
// `data_dir` (paths relative to it). A pair counts when it has >= 30 RANSAC inliers within 3 pixels. Throws
// lmb::Error when an image cannot be read or no pair is usable.
TimeOffsetScan scan_time_offset_visual(const std::filesystem::path& data_dir, const std::vector<TumImage>& images,
                                       const TumTrajectory& trajectory, const Camera& camera, double max_offset_s,
                                       double step_s, double max_gap_s);

}  // namespace lmb
