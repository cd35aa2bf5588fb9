// Localizing a frame with a bundle of area models (infer/area_bundle.h, docs/areas.md).
// BundleLocalizer has one entry point per use: localize() with a position prior (e.g. a GPS fix) or
// none, track() following a camera from frame to frame, and localize_in() over areas the caller chose.
//
// With a prior (position within `radius` metres): the areas whose cell lies within radius + reach of
// the position are candidates, each localized with its own model, nearest first; the search stops as
// soon as the bundle's calibrated verdict over the areas scored so far is localized (a calibrated
// bundle), or at the first area whose own calibrated confidence reaches its operating point (an
// uncalibrated one), and the others are not scored (AreaSearch). When none does, or without a prior
// (every area, in id order), the areas' poses compete (AreaWinner): by default the pose that explains
// most of the frame's keypoints with the matches of EVERY scored area wins, not the one with most
// inliers among its own area's matches (in an aliased place an area that does not hold the frame's
// landmarks matches their look-alikes and gives a wrong pose with more inliers than the right one).
//
//   auto bundle = AreaBundle::open("bundle/bundle.txt");
//   BundleLocalizer localizer(bundle);
//   PositionPrior prior{gps_position, 10.0};
//   BundleLocalizeResult r = localizer.localize(camera, keypoints, descriptors, gravity, &prior);
//   r = localizer.track(camera, keypoints, descriptors, gravity);  // prior: the last pose
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "infer/area_bundle.h"
#include "infer/export.h"
#include "infer/localizer.h"
#include "infer/walk_confidence.h"

namespace lmb {

namespace detail {
class TaskPool;  // infer/detail/task_pool.h
}

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
  // track() with a bundle that has a walk calibration (AreaBundle::walk_calibration): the walk's
  // verdict on the winning pose (infer/walk_confidence.h), and `localized` is walk.localized: the
  // frame rule (confidence >= confidence_threshold) or the walk rule reports the pose, and it agrees
  // with the walk's pose before. frame_localized keeps the frame rule's verdict alone.
  bool walk_judged = false;
  WalkVerdict walk;
  bool frame_localized = false;
  double total_ms = 0.0;  // the whole call, steady clock (loads included)
};

// How the areas a prior selects compete.
enum class AreaSearch : int32_t {
  // The selected areas in the order of their cell's distance from the prior's position (the cell
  // holding it first; ties: the smaller id). With a calibrated bundle (AreaBundle::calibrated),
  // the search stops as soon as the bundle's verdict over the areas scored so far is localized
  // (the winner by AreaWinner, its confidence at the operating point) and the rest are not scored.
  // Without one, the first area whose model is calibrated and whose pose is localized (its
  // confidence reaches the operating point) wins and the rest are not scored. A calibration that
  // saw no wrong pose (PoseCalibration::saw_no_wrong_pose: it reports every pose) stops nothing,
  // the bundle's or an area's; an uncalibrated
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
  // (docs/areas.md measures it). The result is the one-thread result for any area_threads: a wave runs the next areas
  // of the current order
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

  // The areas `prior` selects (every area when null) compete: with a prior as options.search says
  // (AreaSearch), without one every area in id order; the winner by options.winner (AreaWinner).
  // Areas that fail to load are reported in `errors` and skipped. Const and thread-safe (the
  // bundle loads under its own lock).
  BundleLocalizeResult localize(const Camera& camera, const std::vector<Keypoint>& keypoints,
                                const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam,
                                const PositionPrior* prior) const;
  // The areas the caller chose (e.g. by a retrieval of its own), every one scored in the order
  // given (no prior, no early stop), the winner by options.winner. Throws lmb::Error for an id
  // outside the bundle or listed twice. Const and thread-safe, as localize().
  BundleLocalizeResult localize_in(const std::vector<int32_t>& ids, const Camera& camera,
                                   const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                                   const Eigen::Vector3d& gravity_in_cam) const;
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
  // tracking_areas > 1 lets a second area's matches reject most of them (docs/areas.md). With a
  // walk calibration in the bundle, `localized` is the walk's verdict (result.walk): a pose that
  // continues the walk is reported on weaker evidence of its own, one that disagrees with the walk's
  // pose before is refused; a pose the walk reports (not one it refuses) becomes the last pose.
  // `relocalization_prior` (optional, e.g. a GPS fix): a relocalization scores the areas it selects,
  // nearest first (AreaSearch), instead of every area.
  BundleLocalizeResult track(const Camera& camera, const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                             const Eigen::Vector3d& gravity_in_cam,
                             const PositionPrior* relocalization_prior = nullptr);
  // Forgets the last pose and the walk (the next frame is judged as a first frame).
  void reset_tracking();
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
  // New options (checked; throws lmb::Error naming the field); the tracking state is kept (the
  // walk's too, unless localizer.min_confidence changes the frame rule's operating point).
  void set_options(const BundleLocalizerOptions& options);
  AreaBundle& bundle() const { return *bundle_; }
  const std::shared_ptr<AreaBundle>& shared_bundle() const { return bundle_; }
  const BundleLocalizerOptions& options() const { return options_; }

 private:
  std::shared_ptr<AreaBundle> bundle_;
  BundleLocalizerOptions options_;
  // The threads that score a frame's areas (options_.area_threads - 1 workers and the caller);
  // null with one area thread.
  std::shared_ptr<detail::TaskPool> pool_;
  std::optional<Rigid3d> last_pose_;  // set with last_position_, or absent (a position only)
  std::optional<Eigen::Vector3d> last_position_;
  int64_t frames_since_pose_ = 0;  // track() calls since the last pose was set
  // The walk's verdicts in track(): with a calibrated bundle that has a walk calibration.
  std::optional<WalkTracker> walk_;
  double walk_frame_threshold_ = -1.0;  // the frame rule's operating point walk_ was made with
};

}  // namespace lmb
