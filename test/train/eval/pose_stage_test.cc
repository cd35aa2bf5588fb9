// The pose stage's correspondence selection: all accepted matches in keypoint order, or the most
// confident ones (ties in keypoint order) back in keypoint order; and its errors.
#include "train/eval/pose_stage.h"

#include <gtest/gtest.h>

#include "common/error.h"
#include "test/infer/test_models.h"

namespace lmb {
namespace {

EvalQuery query_with(int n) {
  EvalQuery q;
  for (int k = 0; k < n; ++k) {
    Keypoint kp;
    kp.x = static_cast<float>(10 * k);
    kp.y = static_cast<float>(k);
    q.keypoints.push_back(kp);
  }
  return q;
}

Correspondence at(int32_t k, double confidence) {
  return Correspondence{k, 100 + k, Eigen::Vector3d(k, 0, 1), confidence};
}

TEST(PoseStageTest, SelectsTheMostConfidentInKeypointOrder) {
  const EvalQuery q = query_with(6);
  const std::vector<Correspondence> accepted = {at(0, 1.0), at(1, 5.0), at(2, 3.0), at(4, 3.0), at(5, 3.0)};
  const PoseInput all = select_correspondences(q, accepted, 0);
  ASSERT_EQ(all.pixels.size(), 5u);
  EXPECT_EQ(all.pixels[3], Eigen::Vector2d(40, 4));
  EXPECT_EQ(all.points_world[3], Eigen::Vector3d(4, 0, 1));
  // Three of five: 5.0, then the first two of the three tied at 3.0 (keypoints 2 and 4), in keypoint order.
  const PoseInput three = select_correspondences(q, accepted, 3);
  ASSERT_EQ(three.pixels.size(), 3u);
  EXPECT_EQ(three.pixels[0], Eigen::Vector2d(10, 1));
  EXPECT_EQ(three.pixels[1], Eigen::Vector2d(20, 2));
  EXPECT_EQ(three.pixels[2], Eigen::Vector2d(40, 4));
  EXPECT_EQ(select_correspondences(q, accepted, 10).pixels.size(), 5u);
}

// The sweep runs RANSAC once per budget and seed on the same correspondences: each count is the
// outcome of estimate_frame_pose with that budget and seed.
TEST(PoseStageTest, SweepCountsEachBudgetAndSeed) {
  const test::TestWorld w = test::make_test_world(101, 60, 140, 21);
  EvalQuery q;
  q.camera = &w.frame.camera;
  q.keypoints = w.frame.keypoints;
  q.true_cam_from_world = w.frame.cam_from_world;
  std::vector<Correspondence> accepted;
  for (int32_t k = 0; k < static_cast<int32_t>(q.keypoints.size()); ++k) {
    const int32_t cls = w.frame.keypoint_class[k] >= 0 ? w.frame.keypoint_class[k] : (k * 13) % 101;
    accepted.push_back(Correspondence{k, cls, w.positions[cls], 0.0});
  }
  const PoseInput input = select_correspondences(q, accepted, 0);
  PoseSweepOptions options;
  options.iterations = {3, 500};
  options.seeds = 4;
  PoseSweep sweep = start_pose_sweep(options, 7);
  EXPECT_EQ(sweep.seeds, (std::vector<uint64_t>{7, 8, 9, 10}));
  PoseEstimatorOptions pose;
  sweep_frame_pose(q, input, pose, PoseThresholds{}, sweep);
  EXPECT_EQ(sweep.num_frames, 1);
  for (size_t b = 0; b < 2; ++b) {
    for (size_t s = 0; s < 4; ++s) {
      pose.max_iterations = options.iterations[b];
      pose.seed = 7 + s;
      const FrameOutcome o = estimate_frame_pose(q, input, pose);
      EXPECT_EQ(sweep.frames_correct[b][s],
                o.localized && pose_within(o.cam_from_world, o.true_cam_from_world, PoseThresholds{}));
    }
  }
  // 60 of 200 correspondences are exact: 500 iterations find the pose with every seed.
  EXPECT_EQ(sweep.frames_correct[1], (std::vector<int64_t>{1, 1, 1, 1}));
  options.iterations = {0};
  EXPECT_THROW(start_pose_sweep(options, 0), Error);
}

TEST(PoseStageTest, RejectsBadInput) {
  const EvalQuery q = query_with(2);
  EXPECT_THROW(select_correspondences(q, {at(0, 1.0)}, -1), Error);
  EXPECT_THROW(select_correspondences(q, {at(2, 1.0)}, 0), Error);
  EXPECT_THROW(estimate_frame_pose(q, PoseInput{}, PoseEstimatorOptions{}), Error);  // no camera
}

}  // namespace
}  // namespace lmb
