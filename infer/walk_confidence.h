// The confidence of a pose in a walk (a camera localized frame after frame): the probability that
// the pose is right (within 20 cm and 5 degrees of the truth) from the frame's own evidence AND its
// consistency with the walk's last trusted pose, by a logistic model FITTED on walks through map
// frames with known poses (train/eval/walk_calibration_fit.h), never hand-set.
//
//   WalkTracker tracker(model->calibration(), model->walk_calibration());
//   for each frame:
//     LocalizeResult r = localizer.localize(camera, keypoints, descriptors, gravity);
//     WalkVerdict v = tracker.update(r.pose.success, r.pose.cam_from_world, r.evidence);
//     if (v.localized) use(r.pose.cam_from_world);
//
// A pose that continues the walk (a small step from the last trusted pose, for the frames elapsed)
// is strong evidence; one that jumps (a look-alike place elsewhere in the map, a frame from outside
// the map) is weak. The walk features, for a pose with inliers and a last trusted pose at most
// max_gap frames back:
//   0  the frame's logit under the frame calibration (PoseCalibration::logit), clamped to [-30, 30]
//   1  log(1 + translation step / translation_scale_m): the distance between the camera centre and
//      the last trusted one, divided by the frames elapsed (1 = the previous frame was trusted)
//   2  log(1 + rotation step / rotation_scale_deg): the same for the rotation angle
//   3  log(frames elapsed)
// The scales are the median step between consecutive right poses of the calibration walks, so the
// features read the walk's motion in units of the map's own.
//
// The verdict: a pose is reported when the frame rule (the pose calibration at its operating point)
// reports it, or when a trusted pose is at most max_gap frames back and the walk rule (this model at
// its operating point) reports it. So the walk rule only adds poses that continue it: a pose far
// from the last trusted one (a relocalization, a walk recorded at a low frame rate) is judged on its
// own evidence, as a single frame is; a look-alike pose whose own evidence does not carry it is
// refused on the jump even where the walk's continuing poses with the same evidence are reported.
//
// Agreement (when the calibration has one): neither rule reports a pose that disagrees with the
// pose estimated for the nearest earlier frame that has one, at most max_gap frames back (trusted
// or not). Two poses g frames apart agree when their camera centres are at
// most sqrt(2) * noise_m + g * step_m apart and their rotations at most sqrt(2) * noise_deg +
// g * step_deg: noise is how far a right pose strays from the truth, step how far the camera moves
// in a frame, both measured on the map (train/eval/walk_calibration_fit.h). Two right poses of
// neighbouring frames agree; a pose that jumps to a look-alike place, or that wanders by more than
// a right pose does from one frame to the next, is refused whatever its own evidence. A frame with
// no pose in the max_gap frames before it (the walk's first frame, a relocalization) is judged by
// the frame rule alone. The test assumes the walk moves per frame as the map's walks do (video at
// the map's frame rate or faster), so it applies only once the walk has shown that: at least
// kMinComparisons of its poses compared so far, at most half of them disagreeing. A sequence of
// photos metres apart, whose right poses disagree with each other, keeps the frame rule alone.
//
// Threading: WalkCalibration is a value; a WalkTracker follows one walk from one thread.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/rigid3.h"
#include "infer/export.h"
#include "infer/pose_confidence.h"

namespace lmb {

struct LMB_INFER_EXPORT WalkEvidence {
  static constexpr int kNumFeatures = 4;
  double frame_logit = 0.0;         // see feature 0
  double translation_step_m = 0.0;  // camera centre distance to the last trusted pose / frames elapsed
  double rotation_step_deg = 0.0;   // rotation angle to the last trusted pose / frames elapsed
  int32_t frames_elapsed = 1;       // frames since the last trusted pose, >= 1
  // Feature names, for reports ("frame_logit", ...).
  static const std::array<const char*, kNumFeatures>& feature_names();
};

// The step from `last_trusted` to `pose` over `frames_elapsed` (>= 1) frames, and the frame's
// logit; throws lmb::Error for frames_elapsed < 1.
LMB_INFER_EXPORT WalkEvidence walk_evidence(double frame_logit, const Rigid3d& last_trusted, const Rigid3d& pose,
                                            int32_t frames_elapsed);

// A logistic model of P(pose right | walk evidence) and its operating point.
struct LMB_INFER_EXPORT WalkCalibration {
  std::array<double, WalkEvidence::kNumFeatures> weights{};
  double bias = 0.0;
  double threshold = 0.5;            // a pose counts as a success at this probability, in [0, 1]
  double translation_scale_m = 1.0;  // > 0, finite
  double rotation_scale_deg = 1.0;   // > 0, finite
  int32_t max_gap = 3;               // frames elapsed at most for the walk rule and agreement, 1..1000
  // The walk rule (the logistic above) reports poses beside the frame rule; false when it could
  // not be fitted (no wrong sample to tell a jump from): it then reports nothing.
  bool adds = true;
  // Agreement (see the file comment), all >= 0 and finite; noise_m == 0: no agreement test.
  double agreement_noise_m = 0.0;
  double agreement_noise_deg = 0.0;
  double agreement_step_m = 0.0;
  double agreement_step_deg = 0.0;
  int64_t num_samples = 0;  // informative
  int64_t num_positive = 0;
  double target_precision = 0.0;

  // The features in the order of the file comment.
  std::array<double, WalkEvidence::kNumFeatures> features(const WalkEvidence& e) const;
  // sigma(bias + weights . features), in (0, 1).
  double probability(const WalkEvidence& e) const;
  bool has_agreement() const { return agreement_noise_m > 0.0; }
  // The agreement's tolerance for poses g frames apart: sqrt(2) * noise + g * step, metres and
  // degrees (g = 0: the noise part alone).
  double agreement_tolerance_m(int32_t g) const;
  double agreement_tolerance_deg(int32_t g) const;
  // Whether poses a and b of frames frames_apart (>= 1) apart agree (true without agreement).
  bool agrees(const Rigid3d& a, const Rigid3d& b, int32_t frames_apart) const;
  // Throws lmb::Error (prefixed by `where`) naming the field.
  void check(const std::string& where = "walk calibration") const;
};

// Fits the model to evidence[i] labelled right[i] (the logistic fit of fit_pose_calibration, with
// the same options); the scales, max_gap and agreement are taken from `scales`; the threshold is
// left at 0.5.
// Throws lmb::Error when the sizes differ or there is no sample.
LMB_INFER_EXPORT WalkCalibration fit_walk_calibration(const std::vector<WalkEvidence>& evidence,
                                                      const std::vector<char>& right, const WalkCalibration& scales,
                                                      const PoseCalibrationFitOptions& options = {});

// The verdict on one frame of a walk.
struct LMB_INFER_EXPORT WalkVerdict {
  // A trusted pose was at most max_gap frames back: the walk rule judged the frame too.
  bool continues = false;
  double frame_confidence = 0.0;  // the frame rule's probability (0 without a pose)
  double walk_confidence = 0.0;   // the walk rule's (0 without a pose or when not continues)
  bool by_walk = false;           // reported by the walk rule and not by the frame rule
  // The pose was compared with an earlier frame's (agreement), whether it agreed, and whether the
  // test applied (the walk has moved like the map's walks so far): only then does disagreeing
  // refuse the pose.
  bool compared = false;
  bool agrees = true;
  bool agreement_applies = false;
  bool localized = false;  // the pose succeeded and one of the rules reports it
  WalkEvidence evidence;   // meaningful when continues
};

// Follows one walk: judges each frame's pose by the frame rule and, while a trusted pose is at
// most max_gap frames back, by the walk rule too (see the file comment); a reported pose becomes
// the last trusted one. Without a walk calibration every frame is judged by the frame rule.
class LMB_INFER_EXPORT WalkTracker {
 public:
  // Comparisons a walk needs before the agreement test applies (see the file comment).
  static constexpr int32_t kMinComparisons = 3;

  WalkTracker(const PoseCalibration& frame, const std::optional<WalkCalibration>& walk);
  // `success`: the estimator found a pose (PoseResult::success); `evidence` its evidence.
  WalkVerdict update(bool success, const Rigid3d& cam_from_world, const PoseEvidence& evidence);
  // Forgets the last trusted and estimated poses (the next frame is judged as a first frame).
  void reset();
  const std::optional<Rigid3d>& last_trusted() const { return last_; }
  int32_t frames_since_trusted() const { return since_; }

 private:
  void forget_trusted();
  void forget_found();

  PoseCalibration frame_;
  std::optional<WalkCalibration> walk_;
  std::optional<Rigid3d> last_;
  int32_t since_ = 0;                  // frames since last_ (0 right after it was set)
  std::optional<Rigid3d> last_found_;  // the latest pose estimated, trusted or not (agreement)
  int32_t since_found_ = 0;
  int64_t compared_ = 0, disagreed_ = 0;  // the walk's agreement tests so far
};

}  // namespace lmb
