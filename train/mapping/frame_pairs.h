// Choice of the frame pairs the mapper matches: covisible by the known poses (camera centres close,
// viewing directions similar) plus near neighbours in capture order within a session. Query-query
// pairs are never chosen: query frames only need their link to the map. Frames of different map
// sessions pair like any others, so tracks join the sessions. Outside frames (recorded elsewhere)
// are never paired.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "common/rigid3.h"

namespace lmb {

struct PairOptions {
  // Camera centres at most this far apart (world units). 0: automatic, 8 x the median distance
  // between map frames and their nearest map neighbour. Negative values are refused.
  double max_center_distance = 0.0;
  double max_view_angle_deg = 60.0;  // angle between the optical axes
  int max_pairs_per_frame = 20;      // the closest candidates per frame by distance and angle
  int sequence_neighbors = 2;        // map frames i and its next k map frames of the same session always pair
  void check() const;                // throws lmb::Error naming the field
};

struct PairFrame {
  Rigid3d cam_from_world;
  bool is_query = false;  // not a map frame (query or outside)
  int32_t session = 0;    // frames in capture order within a session
  bool outside = false;   // recorded where the map is not: never paired (implies is_query)
};

// Returns pairs (i, j), i < j, sorted and unique. Deterministic.
std::vector<std::pair<int, int>> select_frame_pairs(const std::vector<PairFrame>& frames, const PairOptions& options);

// The distance used when max_center_distance <= 0 (see PairOptions); 0 with fewer than 2 map frames.
double automatic_pair_distance(const std::vector<PairFrame>& frames);

}  // namespace lmb
