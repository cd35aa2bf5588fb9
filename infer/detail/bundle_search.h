// The search over a bundle's areas for one frame (infer/bundle_localizer.h): the areas scored in an
// order, each through its own model; after each, the verdict over the areas scored so far (the
// winner by AreaWinner, its rival, the bundle's evidence and confidence) decides whether the search
// stops (a calibrated verdict, an area's own calibrated pose, the motion gate) and, with the
// winner's view, which areas come next. Internal to lmb_infer (not installed): BundleLocalizer is
// the public entry point; the tests call these directly.
#pragma once

#include <chrono>
#include <cstdint>
#include <vector>

#include "infer/bundle_localizer.h"

namespace lmb::detail {

class TaskPool;

// How one search runs over `order`.
struct SearchPlan {
  std::vector<int32_t> order;  // the areas, in the order they are scored
  // Stop as AreaSearch::kNearestFirst says: at a calibrated bundle's localized verdict, or (an
  // uncalibrated bundle, no gate) at the first area whose own calibrated pose is localized.
  bool nearest_first = false;
  // track(): once `gate_areas` areas are scored the search also stops where the verdict's winner
  // lies within the gate (and an area's own calibration no longer stops it); result.tracked: the
  // winner lies within the gate, however the search ended. Null: no gate.
  const PositionPrior* gate = nullptr;
  int gate_areas = 1;
  // AreaSearch::kWinnersView: after each scored area whose verdict has a new winner, the areas not
  // yet scored are re-ranked by how many of their landmarks the winning pose sees, then by their
  // distance from this prior's position, then by id. Null: the order stays.
  const PositionPrior* view_prior = nullptr;
};

// Scores `plan.order`'s areas for the frame, `pool`'s threads at a time (null: one): a wave runs
// the next areas of the current order not yet run, and an area run ahead is used only when the
// order reaches it (or never), so the result is the one-thread result for any thread count.
// `start`: when the call began (total_ms).
BundleLocalizeResult search_areas(AreaBundle& bundle, const SearchPlan& plan, const Camera& camera,
                                  const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                                  const Eigen::Vector3d& gravity_in_cam, const LocalizerOptions& options,
                                  AreaWinner winner, TaskPool* pool, std::chrono::steady_clock::time_point start);

// Sorts area ids by their cell's distance from `position` (ties keep their order).
void order_by_distance(const AreaBundle& bundle, const Eigen::Vector3d& position, std::vector<int32_t>* ids);

// Throws lmb::Error naming `where` for an unknown search or winner, or threads outside 1..256.
void check_search_options(AreaSearch search, AreaWinner winner, int area_threads, const char* where);

// One frame in the areas `prior` selects (every area when null), as BundleLocalizer::localize
// with these options, `area_threads` areas at a time.
BundleLocalizeResult localize_in_bundle(AreaBundle& bundle, const Camera& camera,
                                        const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                                        const Eigen::Vector3d& gravity_in_cam, const PositionPrior* prior,
                                        const LocalizerOptions& options = {},
                                        AreaSearch search = AreaSearch::kNearestFirst,
                                        AreaWinner winner = AreaWinner::kSupport, int area_threads = 1);

// One frame in the areas `ids`, as BundleLocalizer::localize_in.
BundleLocalizeResult localize_in_areas(AreaBundle& bundle, const std::vector<int32_t>& ids, const Camera& camera,
                                       const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                                       const Eigen::Vector3d& gravity_in_cam, const LocalizerOptions& options = {},
                                       AreaWinner winner = AreaWinner::kSupport, int area_threads = 1);

}  // namespace lmb::detail
