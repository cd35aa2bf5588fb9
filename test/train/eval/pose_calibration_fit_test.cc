// The pose calibration's fit on map frames (train/eval/pose_calibration_fit.h): the landmarks in
// view of a frame, the operating point's bound on the "elsewhere" frames, and the "elsewhere"
// variant of a frame in a building with a copy of its room elsewhere: the method's matches to the
// copy when the frame's own view is not in the map, a wrong pose as good as the right one; a
// calibration that saw no wrong pose says so, and its walks keep the agreement measured on the map.
#include "train/eval/pose_calibration_fit.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/random.h"
#include "test/infer/test_models.h"
#include "train/boost/training_set.h"
#include "train/eval/walk_calibration_fit.h"

namespace lmb {
namespace {

TEST(PassShareThresholdTest, KnownAnswers) {
  // 100 frames, share 0.01: one may pass, the 2nd highest and below fail.
  const double t = pass_share_threshold({0.2, 0.9, 0.5, 0.1}, 100, 0.01);
  EXPECT_GT(t, 0.5);
  EXPECT_LE(t, 0.9);
  EXPECT_EQ(t, std::nextafter(0.5, 1.0));
  // Share 0: none may pass.
  EXPECT_GT(pass_share_threshold({0.2, 0.9, 0.5}, 100, 0.0), 0.9);
  // Ties fail together: two at 0.7, only one may pass -> both fail.
  EXPECT_GT(pass_share_threshold({0.7, 0.7, 0.3}, 100, 0.01), 0.7);
  // No more than allowed: no bound.
  EXPECT_EQ(pass_share_threshold({0.9, 0.8}, 200, 0.01), 0.0);
  EXPECT_EQ(pass_share_threshold({0.9, 0.8, 0.7}, 3, 1.0), 0.0);
  EXPECT_EQ(pass_share_threshold({}, 0, 0.0), 0.0);
  // 0.07 * 100 is 7.000000000000001 in binary: 7 may pass, not 8.
  std::vector<double> p;
  for (int i = 0; i < 10; ++i) p.push_back(0.05 * i);
  EXPECT_EQ(pass_share_threshold(p, 100, 0.07), std::nextafter(0.05 * 2, 1.0));
  EXPECT_THROW(pass_share_threshold({0.1, 0.2}, 1, 0.5), Error);
  EXPECT_THROW(pass_share_threshold({0.1}, 10, 1.5), Error);
  EXPECT_THROW(pass_share_threshold({0.1}, 10, -0.1), Error);
}

// A room of kRoom landmarks in front of a row of map cameras looking along +z, and its copy
// kCopyZ metres behind them (never in view).
constexpr int kRoom = 60;
constexpr double kCopyZ = -30.0;

LandmarkMap room_and_copy(int num_frames) {
  LandmarkMap map;
  map.descriptor_bytes = 8;
  map.cameras.push_back(test::test_camera());
  map.sessions.push_back(MapSession{"map", SessionKind::kMap});
  for (int copy = 0; copy < 2; ++copy) {
    Rng room(5);  // the same room twice
    for (int i = 0; i < kRoom; ++i) {
      Landmark l;
      const double x = room.uniform() * 4.0 - 2.0, y = room.uniform() * 3.0 - 1.5, z = 4.0 + room.uniform() * 4.0;
      l.position = Eigen::Vector3d(x, y, z + (copy == 1 ? kCopyZ : 0.0));
      map.landmarks.push_back(l);
    }
  }
  const Camera& camera = map.cameras[0];
  for (int f = 0; f < num_frames; ++f) {
    MapFrame frame;
    frame.name = "map/" + std::to_string(f) + ".png";
    const Eigen::Vector3d centre(0.1 * f - 1.5, 0.05 * f, 0.0);
    frame.cam_from_world = Rigid3d(Eigen::Quaterniond::Identity(), -centre);
    frame.first_keypoint = static_cast<int64_t>(map.keypoints.size());
    for (landmark_t l = 0; l < kRoom; ++l) {
      Eigen::Vector2d px;
      if (!camera.project(frame.cam_from_world * map.landmarks[l].position, &px)) continue;
      if (px.x() < 0 || px.y() < 0 || px.x() >= camera.width || px.y() >= camera.height) continue;
      Keypoint kp;
      kp.x = static_cast<float>(px.x());
      kp.y = static_cast<float>(px.y());
      map.keypoints.push_back(kp);
      map.keypoint_landmark.push_back(l);
      ++frame.num_keypoints;
    }
    map.frames.push_back(frame);
  }
  map.descriptors.assign(map.keypoints.size() * map.descriptor_bytes, 0);
  return map;
}

TEST(LandmarksInViewTest, ObservedOrProjectingIntoTheImage) {
  LandmarkMap map = room_and_copy(3);
  // An unobserved landmark straight ahead, one behind, one in front but outside the image.
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(-1.5, 0, 50), Eigen::Vector3d(-1.5, 0, -5), Eigen::Vector3d(-1.5 + 40, 0, 5)}) {
    Landmark l;
    l.position = p;
    map.landmarks.push_back(l);
  }
  const landmark_t ahead = 2 * kRoom, behind = ahead + 1, aside = ahead + 2;
  std::vector<char> view = landmarks_in_view(map, 0);
  ASSERT_EQ(view.size(), map.landmarks.size());
  EXPECT_TRUE(view[ahead]);
  EXPECT_FALSE(view[behind]);
  EXPECT_FALSE(view[aside]);
  for (landmark_t l = 0; l < kRoom; ++l) EXPECT_FALSE(view[l + kRoom]) << l;
  // Every landmark a frame observes is in its view, whatever its position.
  const MapFrame& f = map.frames[1];
  ASSERT_GT(f.num_keypoints, 10);
  const landmark_t observed = map.keypoint_landmark[f.first_keypoint];
  map.landmarks[observed].position = Eigen::Vector3d(0, 0, -100);
  EXPECT_TRUE(landmarks_in_view(map, 1)[observed]);
  EXPECT_THROW(landmarks_in_view(map, 3), Error);
}

// A method that matches every keypoint to its own landmark, and, when that landmark is excluded,
// to the same point of the room's copy: what a classifier of an aliased building does.
class RoomMatcher : public Matcher {
 public:
  explicit RoomMatcher(const LandmarkMap& map) : map_(map) {}
  FrameMatches match(const EvalQuery& q) const override {
    FrameMatches r;
    r.accepted = accepted_without(q, [](landmark_t) { return false; });
    r.ranking.resize(q.keypoints.size());
    return r;
  }
  std::vector<Correspondence> accepted_without(const EvalQuery& q,
                                               const std::function<bool(landmark_t)>& excluded) const override {
    std::vector<Correspondence> out;
    const MapFrame& f = map_.frames[q.frame];
    for (int32_t k = 0; k < f.num_keypoints; ++k) {
      const landmark_t own = map_.keypoint_landmark[f.first_keypoint + k];
      for (landmark_t l : {own, own + kRoom}) {
        if (excluded(l)) continue;
        out.push_back(Correspondence{k, l, map_.landmarks[l].position, 1.0});
        break;
      }
    }
    return out;
  }

 private:
  const LandmarkMap& map_;
};

TEST(FitMethodCalibrationTest, ElsewhereFramesMatchTheCopyAndTheOperatingPointBoundsThem) {
  const LandmarkMap map = room_and_copy(40);
  const RoomMatcher matcher(map);
  PoseCalibrationOptions options;
  const CalibrationFit fit = fit_method_calibration(matcher, map, PoseEstimatorOptions{}, 0, PoseThresholds{}, options);
  ASSERT_EQ(fit.num_frames, 20);  // every 2nd frame
  // Each frame as is: right; elsewhere: its matches moved to the copy, a wrong pose with every
  // correspondence an inlier (removing the frame's own matches would leave none).
  EXPECT_EQ(fit.num_elsewhere, fit.num_frames);
  EXPECT_EQ(fit.num_poses, 2 * fit.num_frames);
  EXPECT_EQ(fit.num_right, fit.num_frames);
  ASSERT_TRUE(fit.fitted);
  EXPECT_TRUE(fit.saw_wrong_pose());
  EXPECT_FALSE(fit.calibration.saw_no_wrong_pose());
  // Both kinds look alike to the evidence: at most floor(0.01 * 20) = 0 elsewhere poses pass.
  EXPECT_EQ(fit.elsewhere_passed, 0);
  EXPECT_GE(fit.calibration.threshold, fit.elsewhere_threshold);
  EXPECT_GE(fit.calibration.threshold, fit.precision_threshold);
  EXPECT_GT(fit.elsewhere_threshold, 0.0);
  // No bound: the operating point is the precision's alone.
  options.max_elsewhere_share = 1.0;
  const CalibrationFit unbounded =
      fit_method_calibration(matcher, map, PoseEstimatorOptions{}, 0, PoseThresholds{}, options);
  EXPECT_EQ(unbounded.elsewhere_threshold, 0.0);
  EXPECT_EQ(unbounded.calibration.threshold, unbounded.precision_threshold);
  options.max_elsewhere_share = 1.5;
  EXPECT_THROW(fit_method_calibration(matcher, map, PoseEstimatorOptions{}, 0, PoseThresholds{}, options), Error);
}

// The frames a model's training held out are its calibration frames (with_holdout_frames): exactly
// those (max_frames unused), or every n-th frame when training held none out; frames that are not
// ascending map frames are refused.
TEST(FitMethodCalibrationTest, TheFramesTrainingHeldOutAreTheCalibrationFrames) {
  const LandmarkMap map = room_and_copy(40);
  const RoomMatcher matcher(map);
  TrainingSetOptions training;
  training.calibration_frames = 8;
  training.calibration_frame_share = 0.5;
  training.min_calibration_frames = 2;
  const std::vector<frame_t> held = calibration_holdout_frames(map, training);
  ASSERT_EQ(held, (std::vector<frame_t>{0, 5, 10, 15, 20, 25, 30, 35}));
  PoseCalibrationOptions options;
  options.max_frames = 3;
  const PoseCalibrationOptions on_held = with_holdout_frames(options, map, training);
  EXPECT_EQ(on_held.frames, held);
  EXPECT_EQ(calibration_frames(map, on_held), held);
  const CalibrationFit fit = fit_method_calibration(matcher, map, PoseEstimatorOptions{}, 0, PoseThresholds{}, on_held);
  EXPECT_EQ(fit.num_frames, 8);
  EXPECT_EQ(fit.num_poses, 16);
  // Training that held none out and no fold models (the defaults without cross-fitting, on 40
  // frames): every n-th frame, max_frames of them.
  TrainingSetOptions no_folds;
  no_folds.calibration_folds = 0;
  const PoseCalibrationOptions legacy = with_holdout_frames(options, map, no_folds);
  EXPECT_TRUE(legacy.frames.empty());
  EXPECT_EQ(calibration_frames(map, legacy), calibration_frames(map, 3));
  EXPECT_EQ(fit_method_calibration(matcher, map, PoseEstimatorOptions{}, 0, PoseThresholds{}, legacy).num_frames, 3);
  // Cross-fitted (the defaults on a map too small to hold frames out): every map-session frame.
  const PoseCalibrationOptions crossed = with_holdout_frames(options, map, TrainingSetOptions{});
  EXPECT_EQ(crossed.frames.size(), map.map_session_frames().size());
  EXPECT_TRUE(std::is_sorted(crossed.frames.begin(), crossed.frames.end()));
  PoseCalibrationOptions bad = on_held;
  bad.frames = {5, 0};
  EXPECT_THROW(calibration_frames(map, bad), Error);
  bad.frames = {40};
  EXPECT_THROW(calibration_frames(map, bad), Error);
}

// Calibration poses that are all right: the fit cannot tell a wrong pose from a right one, so it
// is the constant 0.5 reporting every pose, and the walk calibration is the agreement alone, its
// noise the 0.95-quantile of the poses' errors and its step the map walk's motion a frame.
TEST(FitMethodCalibrationTest, WithoutAWrongPoseTheWalksKeepTheAgreementAlone) {
  const LandmarkMap map = room_and_copy(40);
  PoseCalibrationOptions options;
  std::vector<CalibrationPose> poses;
  for (frame_t f = 0; f < 40; f += 2) {
    options.frames.push_back(f);
    CalibrationPose p;
    p.frame = f;
    p.right = true;
    // Off by f / 2 mm along x: errors 0, 1, ..., 19 mm.
    const Eigen::Vector3d centre = map.frames[f].cam_from_world.center() + Eigen::Vector3d(0.0005 * f, 0, 0);
    p.cam_from_world = Rigid3d(Eigen::Quaterniond::Identity(), -centre);
    p.evidence.num_inliers = 30 + f;
    p.evidence.num_correspondences = 60;
    p.evidence.num_keypoints = 80;
    poses.push_back(p);
  }
  const CalibrationFit fit = fit_calibration_on_poses(poses, 20, options);
  ASSERT_TRUE(fit.fitted);
  EXPECT_FALSE(fit.saw_wrong_pose());
  EXPECT_TRUE(fit.calibration.saw_no_wrong_pose());     // what a model file tells
  EXPECT_FALSE(PoseCalibration{}.saw_no_wrong_pose());  // no samples recorded: not known
  EXPECT_EQ(fit.calibration.threshold, 0.0);
  EXPECT_EQ(fit.calibration.probability(poses[0].evidence), 0.5);
  EXPECT_EQ(fit.calibration.probability(poses[19].evidence), 0.5);
  EXPECT_EQ(fit.passed, 20);
  EXPECT_FALSE(fit.to_json().at("saw_wrong_pose").get<bool>());

  const WalkCalibrationFit walk = fit_walk_calibration_on_map(map, fit, options);
  ASSERT_TRUE(walk.fitted);
  EXPECT_FALSE(walk.calibration.adds);  // no wrong sample: no walk rule
  ASSERT_TRUE(walk.calibration.has_agreement());
  // The nearest-rank 0.95-quantile of 0..19 mm: rank round(0.95 * 19) = 18.
  EXPECT_NEAR(walk.calibration.agreement_noise_m, 0.018, 1e-12);
  EXPECT_NEAR(walk.calibration.agreement_noise_deg, 0.01, 1e-12);  // the floor: no rotation error
  // The map walk moves (0.1, 0.05, 0) m a frame without turning.
  EXPECT_NEAR(walk.calibration.agreement_step_m, std::sqrt(0.0125), 1e-9);
  EXPECT_NEAR(walk.calibration.agreement_step_deg, 0.0, 1e-9);
  EXPECT_FALSE(walk.to_json().at("adds").get<bool>());
  EXPECT_NEAR(walk.to_json().at("agreement").at("noise_m").get<double>(), 0.018, 1e-12);

  // Fewer right poses than min_poses: no agreement, and no walk calibration at all.
  options.min_poses = 21;
  const CalibrationFit few = fit_calibration_on_poses(poses, 20, options);
  EXPECT_FALSE(few.fitted);
  EXPECT_FALSE(fit_walk_calibration_on_map(map, few, options).fitted);
}

}  // namespace
}  // namespace lmb
