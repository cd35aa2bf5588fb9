// A bundle of area models (docs/areas.md): one exported model (model.lbm) per area of a map split
// by `lboost areas`, and an index, bundle.txt, beside them. Opening a bundle reads the index only;
// an area's model is read on its first use (its size and CRC-32 checked against the index) and
// freed by release_except() when no longer needed. A missing or corrupt area fails alone, with one
// line naming it; the other areas still load.
//
// The index (text, `lmb-bundle 1`):
//   lmb-bundle 1
//   reach 5.0558576932189325        metres: how far cameras see (the areas file's reach)
//   areas 21
//   area 0 file area-0.lbm bytes 6246098 crc32 1a2b3c4d landmarks 6866 cell LO_X LO_Y LO_Z HI_X HI_Y HI_Z
//   ...
// `file` is relative to the index's folder; cell ends may be -inf / inf. Lines starting with '#'
// are comments.
//
// Localizing with a prior (position within `radius` metres): the areas whose cell lies within
// radius + reach of the position are scored, each with its own model; without a prior, every area.
// The pose with the most inliers wins (ties: the smaller area id).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "infer/export.h"
#include "infer/localizer.h"
#include "infer/model.h"

namespace lmb {

struct LMB_INFER_EXPORT BundleArea {
  int32_t id = 0;
  std::string file;                                   // the model file, relative to the bundle folder
  uint64_t bytes = 0;                                 // its size
  uint32_t crc32 = 0;                                 // CRC-32 of the whole file
  int64_t landmarks = 0;                              // its classes
  Eigen::Vector3d cell_lo = Eigen::Vector3d::Zero();  // the area's cell (world frame, metres);
  Eigen::Vector3d cell_hi = Eigen::Vector3d::Zero();  // ends may be -inf / +inf
  // Euclidean distance from p to the cell (0 inside).
  double distance(const Eigen::Vector3d& p) const;
};

// Writes bundle.txt atomically. Throws lmb::Error naming the path.
LMB_INFER_EXPORT void write_bundle_index(const std::filesystem::path& path, double reach,
                                         const std::vector<BundleArea>& areas);

// A position prior: the camera centre is within `radius` metres (>= 0) of `position` (world frame).
struct LMB_INFER_EXPORT PositionPrior {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

class LMB_INFER_EXPORT AreaBundle {
 public:
  // Reads and checks the index only. Throws lmb::Error "<index> line <n>: <what>" (or naming the
  // file when it cannot be read).
  static std::shared_ptr<AreaBundle> open(const std::filesystem::path& index);

  const std::vector<BundleArea>& areas() const { return areas_; }
  double reach() const { return reach_; }
  const std::filesystem::path& index_path() const { return index_; }

  // Ids of the areas a prior selects (cell within radius + reach), ascending; every id without one.
  // Throws lmb::Error for a non-finite position or a negative / non-finite radius.
  std::vector<int32_t> select(const PositionPrior* prior) const;

  // The model of area `id`, read on first use. Throws lmb::Error "<bundle folder>: area <id>
  // (<file>): <reason>" (missing file, wrong size or CRC-32, an invalid model) and tries again on
  // the next call. Thread-safe.
  std::shared_ptr<const Model> model(int32_t id);
  bool loaded(int32_t id) const;
  // Frees the models of the areas not in `keep` (a caller holding one keeps it alive).
  void release_except(const std::vector<int32_t>& keep);

 private:
  std::filesystem::path index_;
  double reach_ = 0.0;
  std::vector<BundleArea> areas_;
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<const Model>> models_;  // per area, null until loaded
};

struct LMB_INFER_EXPORT BundleLocalizeResult {
  int32_t area = -1;                // the area whose pose won (-1: no area localized the frame)
  LocalizeResult result;            // its result (empty when area is -1)
  std::vector<int32_t> scored;      // the areas scored (selected and loaded)
  std::vector<int32_t> inliers;     // per scored area: its pose's inliers (0 without a pose)
  std::vector<std::string> errors;  // one line per selected area that could not be loaded
};

// Localizes a frame in the areas `prior` selects (every area when prior is null), each through
// its own model with `options`; the successful pose with the most inliers wins (ties: the smaller
// area id). Areas that fail to load are reported in `errors` and skipped. Arguments as
// Localizer::localize.
LMB_INFER_EXPORT BundleLocalizeResult localize_in_bundle(
    AreaBundle& bundle, const Camera& camera, const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
    const Eigen::Vector3d& gravity_in_cam, const PositionPrior* prior, const LocalizerOptions& options = {});

}  // namespace lmb
