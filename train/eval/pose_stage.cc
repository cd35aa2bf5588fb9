#include "train/eval/pose_stage.h"

#include <algorithm>

#include "common/error.h"

namespace lmb {

PoseInput select_correspondences(const EvalQuery& query, const std::vector<Correspondence>& accepted,
                                 int max_correspondences) {
  LMB_CHECK(max_correspondences >= 0, "select_correspondences: max_correspondences " << max_correspondences
                                                                                      << " must be >= 0");
  std::vector<size_t> order(accepted.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  const size_t limit = static_cast<size_t>(max_correspondences);
  if (limit > 0 && order.size() > limit) {
    std::stable_sort(order.begin(), order.end(),
                     [&](size_t x, size_t y) { return accepted[x].confidence > accepted[y].confidence; });
    order.resize(limit);
    std::sort(order.begin(), order.end());  // back to keypoint order
  }
  PoseInput input;
  for (size_t i : order) {
    const Correspondence& c = accepted[i];
    LMB_CHECK(c.keypoint >= 0 && static_cast<size_t>(c.keypoint) < query.keypoints.size(),
              "select_correspondences: keypoint " << c.keypoint << " out of range [0, " << query.keypoints.size()
                                                  << ")");
    const Keypoint& kp = query.keypoints[static_cast<size_t>(c.keypoint)];
    input.pixels.emplace_back(kp.x, kp.y);
    input.points_world.push_back(c.point_world);
  }
  return input;
}

FrameOutcome estimate_frame_pose(const EvalQuery& query, const PoseInput& input,
                                 const PoseEstimatorOptions& options) {
  LMB_CHECK(query.camera != nullptr, "estimate_frame_pose: query frame " << query.frame << " has no camera");
  const PoseResult pose = estimate_absolute_pose(*query.camera, input.pixels, input.points_world, options);
  FrameOutcome o;
  o.localized = pose.success;
  o.cam_from_world = pose.cam_from_world;
  o.true_cam_from_world = query.true_cam_from_world;
  o.num_correspondences = static_cast<int>(input.pixels.size());
  o.num_inliers = pose.num_inliers;
  o.confidence = pose.num_inliers;
  return o;
}

}  // namespace lmb
