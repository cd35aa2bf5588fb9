// The pose stage's correspondence selection: all accepted matches in keypoint order, or the most
// confident ones (ties in keypoint order) back in keypoint order; and its errors.
#include "train/eval/pose_stage.h"

#include <gtest/gtest.h>

#include "common/error.h"

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

TEST(PoseStageTest, RejectsBadInput) {
  const EvalQuery q = query_with(2);
  EXPECT_THROW(select_correspondences(q, {at(0, 1.0)}, -1), Error);
  EXPECT_THROW(select_correspondences(q, {at(2, 1.0)}, 0), Error);
  EXPECT_THROW(estimate_frame_pose(q, PoseInput{}, PoseEstimatorOptions{}), Error);  // no camera
}

}  // namespace
}  // namespace lmb
