// Context augmentation at training time: a training observation's augmented copy is computed from a
// perturbed copy of its frame, so that the classifier sees the contexts a query frame will show
// rather than only the map session's own. A copy c of frame f:
//   - drops each keypoint j with probability `dropout` (the detector not finding it again);
//   - rotates every gravity-aligned position by one angle ~ N(0, rotation) (gravity error);
//   - moves each kept keypoint by N(0, (position_sigma * s_j)^2) per axis, s_j its own scale
//     (detector localization noise);
//   - multiplies each kept keypoint's scale by exp(N(0, scale_sigma^2)) (scale quantization; the
//     anchor's scale sizes all its regions).
// Every draw is a function of (seed, global keypoint index or frame, copy) alone, so a copy is the
// same on every rank, thread and resume. The anchor of a sample is never dropped: a copy whose own
// keypoint would be dropped is not made (augmented_keypoint_kept), which keeps the drop of every
// other keypoint independent of which samples exist.
//
// The default noise is measured on the map itself (measure_map_noise), not set per data set:
//   - repeatability: over pairs of map frames that share a landmark, the share of the landmarks
//     one frame tracks, projected into the other image, that have a keypoint of a similar size
//     there (tracked or not), corrected for chance (dropout = 1 - repeatability). The share the
//     other frame also tracks (the re-observation rate) is reported beside it: it counts matching
//     failures too, so it is lower;
//   - position: the median reprojection residual of the map's observations in keypoint sizes
//     (diameters), converted to a per-axis sigma (median of a 2D Gaussian's radius = 1.1774 sigma);
//   - scale: along each landmark's track, log(keypoint size / focal length x depth) is constant for
//     an ideal detector; the pooled standard deviation of its deviation from the track mean (the
//     same metric size predicts a landmark's keypoint size in another frame for the repeatability).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/context_embedding.h"
#include "common/landmark_map.h"

namespace lmb {

struct AugmentNoise {
  double dropout = 0.0;         // in [0, 1)
  double position_sigma = 0.0;  // keypoint scales
  double scale_sigma = 0.0;     // natural log
  double rotation_rad = 0.0;
  uint64_t seed = 1;
  // Throws lmb::Error naming the field for a value out of range or not finite.
  void check() const;
  std::string text() const;  // one line, for logs
};

struct MapNoiseEstimate {
  double reobservation_rate = 1.0;  // 1 when no frame pair could be checked
  int64_t projected = 0;            // landmark projections into a covisible frame counted
  // The detector's repeatability: the share of those projections with a keypoint of the other
  // frame near them (any keypoint, tracked or not, of a similar size), less the chance of one
  // being there (the same test beside the projection): (hit - chance) / (1 - chance).
  double repeatability = 1.0;  // 1 when nothing could be tested
  double chance_rate = 0.0;
  int64_t repeat_tests = 0;
  double position_sigma = 0.0;  // keypoint scales (per axis)
  int64_t residuals = 0;        // observations measured
  double scale_sigma = 0.0;
  int64_t track_observations = 0;  // observations in tracks of >= 2 measured
};

// Measures the map's noise (see the file comment) on its map-session frames; at most `max_frames`
// frames (evenly spaced, deterministic) are the reference frames of the re-observation rate.
// Observations whose landmark lies behind the camera or whose keypoint size is not > 0 are skipped.
// Throws lmb::Error for a malformed map (a camera or landmark index out of range).
MapNoiseEstimate measure_map_noise(const LandmarkMap& map, int32_t max_frames = 300);

// Whether global keypoint `keypoint` is kept in copy `copy` (>= 1) of its frame.
bool augmented_keypoint_kept(const AugmentNoise& noise, int64_t keypoint, int32_t copy);

// Copy `copy` (>= 1) of a frame's gravity-aligned keypoints (as map_frame_keypoints gives them;
// keypoint i of the frame is global keypoint first_keypoint + i): the kept keypoints perturbed, in
// their order. *index_in_copy gets, per keypoint of the frame, its index in the copy or -1 when it
// was dropped.
FrameKeypoints augmented_frame(const FrameKeypoints& frame, frame_t frame_id, int64_t first_keypoint,
                               const AugmentNoise& noise, int32_t copy, std::vector<int32_t>* index_in_copy);

}  // namespace lmb
