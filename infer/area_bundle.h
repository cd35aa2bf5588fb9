// A bundle of area models (docs/areas.md): one exported model (model.lbm) per area of a map split
// by `lboost areas`, and an index, bundle.txt, beside them (infer/bundle_index.h). AreaBundle is the
// bundle's model cache: opening it reads the index only; an area's model is read on its first use,
// checked against its entry (size, CRC-32 and its classes: a model of another area or map is
// refused), and freed by release_except() or the cache limits. A missing or corrupt area fails
// alone, with one line naming it; the other areas still load. Localizing with a bundle:
// infer/bundle_localizer.h.
//
// Memory: set_cache_limits() bounds the loaded areas (a count and/or their model bytes); when a
// load would exceed a limit, the least recently used other areas are freed first.
//
//   auto bundle = AreaBundle::open("bundle/bundle.txt");
//   bundle->set_cache_limits({8, 0});                 // at most 8 areas in memory
//   std::shared_ptr<const Model> area = bundle->model(3);
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"
#include "infer/bundle_index.h"
#include "infer/export.h"
#include "infer/model.h"

namespace lmb {

// A position prior: the camera centre is within `radius` metres (>= 0) of `position` (world frame).
struct LMB_INFER_EXPORT PositionPrior {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double radius = 0.0;
  // Throws lmb::Error unless the position is finite and the radius finite and >= 0.
  void check() const;
};

// Limits on the areas a bundle keeps loaded; 0 = no limit.
struct LMB_INFER_EXPORT BundleCacheLimits {
  int64_t max_areas = 0;   // loaded areas
  uint64_t max_bytes = 0;  // the loaded areas' model file bytes (BundleArea::bytes)
};

class LMB_INFER_EXPORT AreaBundle {
 public:
  // Reads and checks the index only. Throws lmb::Error "<index> line <n>: <what>" (or naming the
  // file when it cannot be read).
  static std::shared_ptr<AreaBundle> open(const std::filesystem::path& index);
  // A bundle of an index in memory, as if read from `index_path` (its folder holds the area files):
  // e.g. `lboost bundle` scores the areas before it writes the index. Throws lmb::Error for an
  // index write_bundle_index would refuse.
  static std::shared_ptr<AreaBundle> create(const std::filesystem::path& index_path, BundleIndex index);

  const std::vector<BundleArea>& areas() const { return areas_; }
  double reach() const { return reach_; }
  // fingerprint_map (common/feature_space.h) of the map the areas split; 0 when the index does not
  // record it (versions 1 and 2).
  uint64_t map_fingerprint() const { return map_fingerprint_; }
  // The bundle's pose calibration (version 2 indexes): P(the winning pose is right) from the
  // bundle's evidence (BundleLocalizeResult::evidence).
  bool calibrated() const { return calibration_.has_value(); }
  const PoseCalibration& calibration() const { return *calibration_; }
  // The walk calibration of BundleLocalizer::track (version 4 indexes fitted by `lboost bundle
  // --map`): the walk rule and the agreement of a walk's poses (infer/walk_confidence.h) over the
  // bundle's calibrated confidence. Absent: track() judges each frame alone.
  const std::optional<WalkCalibration>& walk_calibration() const { return walk_calibration_; }
  const std::filesystem::path& index_path() const { return index_; }

  // Ids of the areas a prior selects (cell within radius + reach), ascending; every id without one.
  // Throws lmb::Error for a non-finite position or a negative / non-finite radius.
  std::vector<int32_t> select(const PositionPrior* prior) const;

  // The model of area `id`, read on first use. Throws lmb::Error "<bundle folder>: area <id>
  // (<file>): <reason>" (missing file, wrong size or CRC-32, an invalid model) and tries again on
  // the next call. Thread-safe.
  std::shared_ptr<const Model> model(int32_t id);
  bool loaded(int32_t id) const;
  // A function applied to each area's model as it loads, after the file's checks and before the
  // bundle keeps it (e.g. `lboost bundle --map` fits the calibration on models whose descriptor
  // fusion has no exemplar of the calibration frames' own keypoints). Setting one frees the
  // areas already loaded, so every model the bundle hands out has passed through it; an empty one
  // removes it. It runs outside the bundle's lock (it must be thread-safe when areas are scored in
  // parallel) and must return a model of the same classes; what it throws is the area's load error.
  using ModelTransform = std::function<std::shared_ptr<const Model>(int32_t id, std::shared_ptr<const Model> model)>;
  void set_model_transform(ModelTransform transform);
  // Frees the models of the areas not in `keep` (a caller holding one keeps it alive).
  void release_except(const std::vector<int32_t>& keep);

  // Least-recently-used eviction: after each load, while the loaded areas exceed a limit, the
  // area used longest ago (other than the one just loaded) is freed. Setting limits applies them
  // at once. Throws lmb::Error for negative max_areas.
  void set_cache_limits(const BundleCacheLimits& limits);
  BundleCacheLimits cache_limits() const;
  // The loaded areas, ascending, and their model file bytes.
  std::vector<int32_t> loaded_ids() const;
  uint64_t loaded_bytes() const;
  // How many times an area's model was read from its file (loads after an eviction count again).
  int64_t loads() const;
  // How many of area `id`'s landmarks a camera at `cam_from_world` sees: in front of it, within
  // reach() (when > 0) and inside `camera`'s image. Counted over a fixed sample of at most
  // kViewSample of the area's landmarks, taken when the area first loads and kept after it is freed
  // (so ranking areas by view does not keep them in memory); the first call loads the area. Throws
  // as model().
  static constexpr size_t kViewSample = 1024;
  int32_t visible_landmarks(int32_t id, const Camera& camera, const Rigid3d& cam_from_world);

  // The descriptor length of the areas (-1 until one has loaded). Every area must have the first
  // loaded area's: one with another fails to load, naming both lengths.
  int32_t descriptor_bytes() const;
  // The same, first loading the first of `ids` that loads when no area has loaded yet (-1 when
  // none does: then none of them can be scored and a frame's descriptors are not read).
  int32_t descriptor_bytes(const std::vector<int32_t>& ids);

 private:
  void evict_locked(int32_t keep);  // mutex_ held

  std::filesystem::path index_;
  double reach_ = 0.0;
  uint64_t map_fingerprint_ = 0;
  std::optional<PoseCalibration> calibration_;
  std::optional<WalkCalibration> walk_calibration_;
  std::vector<BundleArea> areas_;
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<const Model>> models_;  // per area, null until loaded
  std::vector<uint64_t> last_use_;                    // per area: the use clock at its last use
  // Per area: a sample of its landmark positions (visible_landmarks), empty until it first loads.
  std::vector<std::shared_ptr<const std::vector<Eigen::Vector3d>>> view_samples_;
  uint64_t use_clock_ = 0;
  int64_t loads_ = 0;
  int32_t descriptor_bytes_ = -1;
  BundleCacheLimits limits_;
  ModelTransform transform_;
};

}  // namespace lmb
