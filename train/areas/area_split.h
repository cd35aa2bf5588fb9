// Splitting a map into overlapping areas, one classifier each (docs/areas.md).
//
// An area is a cell of a k-d partition of space by the eligible landmarks' positions (a landmark
// is eligible with at least min_observations map observations): while its area would hold more
// than max_classes landmarks, a cell is split along its landmarks' widest axis (between their 5%
// and 95% quantiles) into two cells
// holding floor(P/2) : ceil(P/2) of them, P = the number of max_classes areas they need. The
// area of a cell holds the eligible landmarks inside the cell and, for overlap, those within
// `overlap` metres of it, so that landmarks near a border are in the areas on both sides. The cells
// partition all of space (outer cells reach to infinity): every eligible landmark lies in exactly
// one cell and so is in at least one area.
//
// A camera sees landmarks up to some distance: `reach`, by default the 90th percentile of the map
// frames' observation distances (camera centre to landmark). A position prior (centre, radius)
// selects the areas whose cell lies within radius + reach of the centre: when the true camera is
// within the radius, every landmark it sees within `reach` is in a selected area.
//
// A cell whose landmarks cannot be halved (all at one position) keeps its own landmarks first, then
// the nearest overlap ones (Area::num_truncated counts the rest). Everything is deterministic: ties
// go to the smaller landmark id, no random draws.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "common/landmark_map.h"
#include "common/types.h"

namespace lmb {

struct AreaSplitOptions {
  int32_t max_classes = 7500;    // K: landmarks per area at most (>= 1)
  int32_t min_observations = 5;  // N: a landmark needs this many map observations (>= 1)
  double overlap = 1.0;          // metres (world units): landmarks this close to a cell join its area
  double reach = 0.0;            // metres: how far cameras see; 0 = the map's 90th percentile
  void check() const;            // throws lmb::Error naming the option
};

// An axis-aligned box in world coordinates; an end may be -inf / +inf.
struct AreaBox {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  // Euclidean distance from p to the box (0 inside or on it).
  double distance(const Eigen::Vector3d& p) const;
};

struct Area {
  int32_t id = 0;                     // 0..num_areas-1, in k-d order (lower half first)
  AreaBox cell;                       // the k-d cell (the areas' cells partition space)
  AreaBox bounds;                     // bounding box of its landmarks (finite)
  int64_t num_core = 0;               // its landmarks inside the cell (the rest are overlap)
  int64_t num_truncated = 0;          // overlap landmarks left out to respect max_classes
  std::vector<landmark_t> landmarks;  // sorted ascending, at most max_classes
};

struct AreaSplit {
  AreaSplitOptions options;  // reach: the value used (never 0 after a split)
  int64_t num_eligible = 0;  // landmarks with >= min_observations map observations
  std::vector<Area> areas;
};

// Map observations (keypoints of map, i.e. non-query, frames) per landmark.
std::vector<int32_t> map_observation_counts(const LandmarkMap& map);

// The `q` quantile (0..1) of the distances from map cameras to the landmarks they observe.
// Throws lmb::Error when the map has no map observation.
double map_observation_distance(const LandmarkMap& map, double q);

// The split of `map` (its map frames; query frames are never looked at). Throws lmb::Error on a
// malformed map (keypoint ranges, landmark ids) or no eligible landmark.
AreaSplit split_map_into_areas(const LandmarkMap& map, const AreaSplitOptions& options);

// Ids of the areas whose cell lies within `radius` of `position` (radius >= 0; 0 = the cells that
// contain it), ascending. A prior selects areas_near(centre, prior radius + split.options.reach).
std::vector<int32_t> areas_near(const AreaSplit& split, const Eigen::Vector3d& position, double radius);

// Eligible landmarks (as split_map_into_areas counts them) that no area holds, ascending.
std::vector<landmark_t> uncovered_landmarks(const LandmarkMap& map, const AreaSplit& split);

// How well the areas a position prior selects cover the query frames' keypoints. The prior of a
// query frame is its true camera centre moved `prior_noise` metres in a direction drawn from
// (seed, frame id); the selected areas are areas_near(prior, prior_noise + reach).
struct AreaCoverage {
  int32_t num_query_frames = 0;
  int64_t num_keypoints = 0;         // query keypoints with a true landmark
  int64_t num_eligible = 0;          // ... that is eligible (the most any split can cover)
  int64_t num_covered_any = 0;       // ... whose landmark one of the frame's selected areas holds
  int64_t num_covered_best = 0;      // ... held by the frame's best single selected area
  double mean_selected_areas = 0.0;  // areas selected per query frame
  int32_t max_selected_areas = 0;
};
AreaCoverage query_coverage(const LandmarkMap& map, const AreaSplit& split, double prior_noise, uint64_t seed = 1);

// The unit direction of the prior offset of frame `frame` (uniform on the sphere).
Eigen::Vector3d prior_direction(uint64_t seed, int64_t frame);

}  // namespace lmb
