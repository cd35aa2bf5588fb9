// What `lboost inspect` reports of a map.h5: frames, sessions, keypoints, landmarks and their
// observations and quality; the descriptor aliasing figure (exact Hamming nearest neighbour
// precision@1 of query keypoints against the map's keypoints, descriptor_nn.h); and, for a rendered
// world, the map checked against its depth (depth_ground_truth.h).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "common/landmark_map.h"

namespace lmb {

struct MapReportOptions {
  bool hamming_nn = true;        // the Hamming nearest-neighbour figure
  int threads = 2;               // its threads
  std::string depth_collection;  // a rendered world folder with depth/: check the map against it
};

// The map's statistics (counts per kind of frame and session, observations, quality).
nlohmann::json map_statistics(const LandmarkMap& map);

// map_statistics and what `options` asks for, as one JSON object.
nlohmann::json map_report(const LandmarkMap& map, const MapReportOptions& options);

// The report as lines of text, as `lboost inspect` prints them.
std::string map_report_text(const nlohmann::json& report);

}  // namespace lmb
