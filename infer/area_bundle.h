// A bundle of area models (docs/areas.md): one exported model (model.lbm) per area of a map split
// by `lboost areas`, and an index, bundle.txt, beside them. Opening a bundle reads the index only;
// an area's model is read on its first use (its size and CRC-32 checked against the index) and
// freed by release_except() when no longer needed. A missing or corrupt area fails alone, with one
// line naming it; the other areas still load.
//
// The index (text, `lmb-bundle 1`, or 2 with a calibration):
//   lmb-bundle 2
//   reach 5.0558576932189325        metres: how far cameras see (the areas file's reach)
//   calibration W0 .. W6 BIAS THRESHOLD SAMPLES POSITIVE PRECISION   (version 2 only: the bundle's
//                                   pose calibration, PoseCalibration's fields, fitted by `lboost bundle --map`)
//   areas 21
//   area 0 file area-0.lbm bytes 6246098 crc32 1a2b3c4d landmarks 6866 cell LO_X LO_Y LO_Z HI_X HI_Y HI_Z
//   ...
// `file` is relative to the index's folder; cell ends may be -inf / inf. Lines starting with '#'
// are comments.
//
// Localizing with a prior (position within `radius` metres): the areas whose cell lies within
// radius + reach of the position are candidates, each localized with its own model, nearest first;
// the search stops as soon as the bundle's calibrated verdict over the areas scored so far is
// localized (a calibrated bundle), or at the first area whose own calibrated confidence reaches
// its operating point (an uncalibrated one), and the others are not scored (AreaSearch). When none does, or without a
// prior (every area, in id order), the areas' poses compete (AreaWinner): by default the pose that explains most of the
// frame's keypoints with the matches of EVERY scored area wins, not the one with most inliers among its own area's
// matches (in an aliased place an area that does not hold the frame's landmarks matches their
// look-alikes and gives a wrong pose with more inliers than the right one; docs/areas.md).
//
// Memory: set_cache_limits() bounds the loaded areas (a count and/or their model bytes); when a
// load would exceed a limit, the least recently used other areas are freed first.
//
//   auto bundle = AreaBundle::open("bundle/bundle.txt");
//   bundle->set_cache_limits({8, 0});                 // at most 8 areas in memory
//   BundleLocalizer localizer(bundle);
//   PositionPrior prior{gps_position, 10.0};
//   BundleLocalizeResult r = localizer.localize(camera, keypoints, descriptors, gravity, &prior);
//   r = localizer.track(camera, keypoints, descriptors, gravity);  // prior: the last pose
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

// Writes bundle.txt atomically: version 1, or 2 with a calibration (non-null). Throws lmb::Error
// naming the path.
LMB_INFER_EXPORT void write_bundle_index(const std::filesystem::path& path, double reach,
                                         const std::vector<BundleArea>& areas,
                                         const PoseCalibration* calibration = nullptr);

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

  const std::vector<BundleArea>& areas() const { return areas_; }
  double reach() const { return reach_; }
  // The bundle's pose calibration (version 2 indexes): P(the winning pose is right) from the
  // bundle's evidence (BundleLocalizeResult::evidence).
  bool calibrated() const { return calibration_.has_value(); }
  const PoseCalibration& calibration() const { return *calibration_; }
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
  std::optional<PoseCalibration> calibration_;
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

struct LMB_INFER_EXPORT BundleLocalizeResult {
  int32_t area = -1;             // the area whose pose won (-1: no area localized the frame)
  LocalizeResult result;         // its result (empty when area is -1)
  std::vector<int32_t> scored;   // the areas scored (selected and loaded)
  std::vector<int32_t> inliers;  // per scored area: its pose's inliers (0 without a pose)
  // Per scored area: the frame's keypoints its pose explains with the matches of every scored
  // area (count_explained_keypoints; 0 without a pose).
  std::vector<int32_t> support;
  // The winner's rival: the most keypoints another scored area's pose explains with matches the
  // winning pose does not explain (count_explained_keypoints' unless_explained_by); 0 without a
  // winner or another pose. An agreeing pose counts ~0; in an aliased place a look-alike pose
  // comes close to the winner's support.
  int32_t rival_support = 0;
  // The winning pose's evidence over the whole bundle (infer/pose_confidence.h): its support as
  // the inliers, the keypoints with a match in some scored area as the correspondences, the rival
  // support as the runner-up, the winning area's inlier rank and spread.
  PoseEvidence evidence;
  // With a calibrated bundle: P(the winning pose is right) and the operating point applied (the
  // bundle's, or options.min_confidence when >= 0); -1 otherwise.
  bool calibrated = false;
  double confidence = -1.0;
  double confidence_threshold = -1.0;
  // The answer to act on: a winning pose and, with a calibrated bundle, confidence >= threshold;
  // with an uncalibrated one, the winning area's own LocalizeResult::localized.
  bool localized = false;
  std::vector<std::string> errors;  // one line per selected area that could not be loaded
  int32_t selected = 0;             // areas the prior selected (every area without one)
  int32_t loaded = 0;               // areas read from their files during this call
  bool prior_used = false;          // a prior restricted the areas (track(): false = relocalized)
  // track(): the winning pose lies within the motion gate of the last tracked pose
  // (BundleLocalizer::track). The tracker's own evidence, apart from `localized`.
  bool tracked = false;
  double total_ms = 0.0;  // the whole call, steady clock (loads included)
};

// How the areas a prior selects compete.
enum class AreaSearch : int32_t {
  // The selected areas in the order of their cell's distance from the prior's position (the cell
  // holding it first; ties: the smaller id). With a calibrated bundle (AreaBundle::calibrated),
  // the search stops as soon as the bundle's verdict over the areas scored so far is localized
  // (the winner by AreaWinner, its confidence at the operating point) and the rest are not scored.
  // Without one, the first area whose model is calibrated and whose pose is localized (its
  // confidence reaches the operating point) wins and the rest are not scored; an uncalibrated
  // model's pose never stops the search (its inlier count alone is not trusted: wrong poses with
  // dozens of inliers are common where areas cut a view). When nothing stops it, every selected
  // area has been scored and the rule of kAll decides. Without a prior: kAll.
  kNearestFirst = 0,
  // Every selected area is scored; AreaWinner decides.
  kAll = 1,
  // kNearestFirst with the remaining areas re-ranked after each scored area: once the areas scored
  // so far have a winning pose (AreaWinner), the rest go in the order of how many of their
  // landmarks that pose sees (AreaBundle::visible_landmarks: the first ranking loads an area once
  // for its landmark sample), then by distance, then the smaller id; the same stops. The areas
  // that hold the candidate pose's view come sooner, so a calibrated stop comes after fewer areas
  // (`paper`, 5 m prior: 9.2-9.4 areas instead of 10.7, docs/areas.md). The result is the
  // one-thread result for any area_threads: a wave runs the next areas of the current order
  // ahead, and an area run ahead is used only when the one-thread order reaches it. In track(),
  // the relocalization with a prior; the tracked areas keep the last pose's view order.
  kWinnersView = 2,
};

// Which of the scored areas' poses wins when the search did not stop at a calibrated pose.
enum class AreaWinner : int32_t {
  // The pose that explains most keypoints of the frame: a keypoint counts when one of its matches
  // from ANY scored area (each area's pose_top_k best, the correspondences it gave RANSAC) passes
  // the estimator's inlier test at that pose (count_explained_keypoints, the same threshold).
  // Ties: more inliers of its own, then the smaller area id. A right pose is confirmed by every
  // area that holds part of the view; a pose made of one area's look-alike matches is not.
  kSupport = 0,
  // The pose with the most inliers among its own area's matches (ties: the smaller area id).
  kInliers = 1,
};

// Localizes a frame in the areas `prior` selects (every area when prior is null), each through
// its own model with `options`, the winner chosen by `search` and `winner`, `area_threads` areas
// at a time (BundleLocalizerOptions::area_threads). Areas that fail to load are reported in
// `errors` and skipped. Arguments as Localizer::localize.
LMB_INFER_EXPORT BundleLocalizeResult localize_in_bundle(
    AreaBundle& bundle, const Camera& camera, const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
    const Eigen::Vector3d& gravity_in_cam, const PositionPrior* prior, const LocalizerOptions& options = {},
    AreaSearch search = AreaSearch::kNearestFirst, AreaWinner winner = AreaWinner::kSupport, int area_threads = 1);

// The same over areas the caller chose (e.g. by a retrieval of its own), every one scored in the
// order given (no prior, no early stop), the winner chosen by `winner`. Throws lmb::Error for an id
// outside the bundle or listed twice.
LMB_INFER_EXPORT BundleLocalizeResult localize_in_areas(AreaBundle& bundle, const std::vector<int32_t>& ids,
                                                        const Camera& camera, const std::vector<Keypoint>& keypoints,
                                                        const uint8_t* descriptors,
                                                        const Eigen::Vector3d& gravity_in_cam,
                                                        const LocalizerOptions& options = {},
                                                        AreaWinner winner = AreaWinner::kSupport, int area_threads = 1);

struct LMB_INFER_EXPORT BundleLocalizerOptions {
  LocalizerOptions localizer;
  AreaSearch search = AreaSearch::kNearestFirst;  // with a prior (and in track()): see AreaSearch
  AreaWinner winner = AreaWinner::kSupport;       // which scored area's pose wins: see AreaWinner
  // Areas localized at once, each on its own thread (1..256; 1 = the calling thread only). The
  // result is the same for any count: with nearest first, the areas scored after the one that
  // stops the search in its wave of `area_threads` are dropped (their work is wasted).
  int area_threads = 1;
  // track(): the prior is the last tracked camera centre within this many metres (how far the
  // camera may move between two tracked frames; the bundle's reach is added by the selection), and
  // the motion gate: the first area whose pose lies this close to the last tracked pose wins.
  double tracking_radius = 1.0;
  // track(): the motion gate is judged once this many areas are scored (1..256): the pose that wins
  // among them (AreaWinner) must lie within tracking_radius. More areas cost more time and let the
  // support rule reject a look-alike pose that happens to lie within the gate.
  int tracking_areas = 2;
  // track(): when the tracked areas give neither a gated nor a trusted pose, relocalize (in every
  // area, or in those track()'s relocalization prior selects); false: report the failed frame. The
  // first frame (no last pose) is always relocalized.
  bool relocalize_without_prior = true;
  // Throws lmb::Error naming the field.
  void check() const;
};

// Localization over an AreaBundle, the C++ counterpart of Localizer for a map split into areas.
// localize() is const and thread-safe (the bundle loads under its own lock); track() keeps the
// last pose, so one BundleLocalizer tracks one camera from one thread at a time.
class LMB_INFER_EXPORT BundleLocalizer {
 public:
  // Throws lmb::Error for a null bundle or invalid options.
  explicit BundleLocalizer(std::shared_ptr<AreaBundle> bundle, const BundleLocalizerOptions& options = {});

  // The areas `prior` selects (every area when null) compete (options.search); see localize_in_bundle.
  BundleLocalizeResult localize(const Camera& camera, const std::vector<Keypoint>& keypoints,
                                const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam,
                                const PositionPrior* prior) const;
  // Tracking mode. With a last tracked pose, the areas within options.tracking_radius of its
  // centre (times 1 + the frames since it was set: the camera moves at most that far a frame; plus
  // the reach) are scored in the order of how many of their landmarks that pose sees (most first; by
  // distance when only a position is known). With AreaSearch::kNearestFirst, once tracking_areas
  // areas are scored the search stops where the winning pose lies within that radius of the last
  // one and its support exceeds its rival's: the motion gate (result.tracked; `localized` keeps its
  // meaning, the bundle's calibrated verdict). The calibrated stop of kNearestFirst applies too, an
  // area's own calibration does not. Without a last pose (first frame, after reset_tracking()), or
  // when the tracked areas give neither a gated nor a trusted pose and relocalize_without_prior is
  // set, every area is scored (result.prior_used false; with a last pose, a winner that passes the
  // gate is tracked too). A tracked pose, or a trusted one (with a calibrated bundle `localized`,
  // without one any winning pose), becomes the last pose. A look-alike pose can pass the gate:
  // tracking_areas > 1 lets a second area's matches reject most of them (docs/areas.md).
  // `relocalization_prior` (optional, e.g. a GPS fix): a relocalization scores the areas it selects,
  // nearest first (AreaSearch), instead of every area.
  BundleLocalizeResult track(const Camera& camera, const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                             const Eigen::Vector3d& gravity_in_cam,
                             const PositionPrior* relocalization_prior = nullptr);
  void reset_tracking() { set_last_pose(std::nullopt); }
  // Sets the last tracked pose (cam_from_world), e.g. predicted by odometry, or none.
  void set_last_pose(const std::optional<Rigid3d>& cam_from_world);
  // Sets the last tracked camera centre without an orientation (areas then by distance), or none.
  void set_last_position(const std::optional<Eigen::Vector3d>& position) {
    last_pose_.reset();
    last_position_ = position;
    frames_since_pose_ = 0;
  }
  // The last tracked pose and camera centre (world frame), if any.
  const std::optional<Rigid3d>& last_pose() const { return last_pose_; }
  const std::optional<Eigen::Vector3d>& last_position() const { return last_position_; }
  // New options (checked; throws lmb::Error naming the field); the tracking state is kept.
  void set_options(const BundleLocalizerOptions& options) {
    options.check();
    options_ = options;
  }
  AreaBundle& bundle() const { return *bundle_; }
  const std::shared_ptr<AreaBundle>& shared_bundle() const { return bundle_; }
  const BundleLocalizerOptions& options() const { return options_; }

 private:
  std::shared_ptr<AreaBundle> bundle_;
  BundleLocalizerOptions options_;
  std::optional<Rigid3d> last_pose_;  // set with last_position_, or absent (a position only)
  std::optional<Eigen::Vector3d> last_position_;
  int64_t frames_since_pose_ = 0;  // track() calls since the last pose was set
};

}  // namespace lmb
