// What `lboost inspect` reports of a map.h5: frames, sessions, keypoints, landmarks and their
// observations and quality; the descriptor aliasing figure (exact Hamming nearest neighbour
// precision@1 of query keypoints against the map's keypoints, descriptor_nn.h); and, for a rendered
// world, the map checked against its depth (depth_ground_truth.h).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/landmark_map.h"
#include "train/mapping/mapper.h"

namespace lmb {

struct MapReportOptions {
  bool hamming_nn = true;        // the Hamming nearest-neighbour figure
  int threads = 2;               // its threads
  std::string depth_collection;  // a rendered world folder with depth/: check the map against it
};

// The map's statistics (counts per kind of frame and session, observations, quality, the
// reprojection error per frame).
nlohmann::json map_statistics(const LandmarkMap& map);

// One frame's fit to the map: its keypoints with a landmark and their mean reprojection error
// (pixels: each landmark projected with the frame's camera and pose against the keypoint).
struct FrameReprojection {
  frame_t frame = 0;
  int64_t observations = 0;
  double mean_error_px = 0;  // 0 without observations
};
std::vector<FrameReprojection> frame_reprojection_errors(const LandmarkMap& map);

// The per-frame errors summarized: over the frames with observations, the mean, median and 90th
// percentile of their mean errors, and the `worst` frames (name, error, observations), worst first.
// Wrong intrinsics or poses show as a high mean (all frames) or as a few bad frames.
nlohmann::json frame_reprojection_summary(const LandmarkMap& map, int worst = 5);

// The summary as one line of text (no newline).
std::string frame_reprojection_text(const nlohmann::json& summary);

// map_statistics and what `options` asks for, as one JSON object.
nlohmann::json map_report(const LandmarkMap& map, const MapReportOptions& options);

// What the mapper did (lboost map --report): frame pairs and their choice, matches, tracks, times
// and, with camera refinement, the cameras and reprojection errors before and after.
nlohmann::json mapper_statistics(const MapperStats& stats);

// The camera refinement of `stats` as one line of text per camera (empty without refinement).
std::string camera_refinement_text(const MapperStats& stats);

// The report as lines of text, as `lboost inspect` prints them.
std::string map_report_text(const nlohmann::json& report);

}  // namespace lmb
