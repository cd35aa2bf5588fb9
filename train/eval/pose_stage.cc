#include "train/eval/pose_stage.h"

#include <algorithm>

#include "common/error.h"

namespace lmb {

PoseInput select_correspondences(const EvalQuery& query, const std::vector<Correspondence>& accepted,
                                 int max_correspondences) {
  LMB_CHECK(max_correspondences >= 0,
            "select_correspondences: max_correspondences " << max_correspondences << " must be >= 0");
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
    LMB_CHECK(
        c.keypoint >= 0 && static_cast<size_t>(c.keypoint) < query.keypoints.size(),
        "select_correspondences: keypoint " << c.keypoint << " out of range [0, " << query.keypoints.size() << ")");
    const Keypoint& kp = query.keypoints[static_cast<size_t>(c.keypoint)];
    input.pixels.emplace_back(kp.x, kp.y);
    input.points_world.push_back(c.point_world);
    input.quality.push_back(c.confidence);
  }
  return input;
}

FrameOutcome estimate_frame_pose(const EvalQuery& query, const PoseInput& input, const PoseEstimatorOptions& options) {
  LMB_CHECK(query.camera != nullptr, "estimate_frame_pose: query frame " << query.frame << " has no camera");
  const PoseResult pose =
      estimate_absolute_pose(*query.camera, input.pixels, input.points_world, options, input.quality);
  FrameOutcome o;
  o.localized = pose.success;
  o.cam_from_world = pose.cam_from_world;
  o.true_cam_from_world = query.true_cam_from_world;
  o.num_correspondences = static_cast<int>(input.pixels.size());
  o.num_inliers = pose.num_inliers;
  o.confidence = pose.num_inliers;
  o.evidence =
      pose_evidence(*query.camera, input.pixels, input.quality, pose, static_cast<int>(query.keypoints.size()));
  return o;
}

void PoseSweepOptions::check() const {
  LMB_CHECK(!iterations.empty(), "PoseSweepOptions: no iteration budget");
  for (int it : iterations) LMB_CHECK(it >= 1, "PoseSweepOptions: iteration budget " << it << " must be >= 1");
  LMB_CHECK(seeds >= 1 && seeds <= 1000, "PoseSweepOptions: seeds " << seeds << " must be in 1..1000");
}

PoseSweep start_pose_sweep(const PoseSweepOptions& sweep_options, uint64_t base_seed, bool calibrated) {
  sweep_options.check();
  PoseSweep sweep;
  sweep.iterations = sweep_options.iterations;
  for (int s = 0; s < sweep_options.seeds; ++s) sweep.seeds.push_back(base_seed + static_cast<uint64_t>(s));
  sweep.frames_correct.assign(sweep.iterations.size(), std::vector<int64_t>(sweep.seeds.size(), 0));
  sweep.frames_localized = sweep.frames_correct;
  if (calibrated) {
    sweep.calibrated_localized = sweep.frames_correct;
    sweep.calibrated_correct = sweep.frames_correct;
  }
  return sweep;
}

void sweep_frame_pose(const EvalQuery& query, const PoseInput& input, const PoseEstimatorOptions& options,
                      const PoseThresholds& thresholds, PoseSweep& sweep, const PoseCalibration* calibration,
                      std::vector<FrameOutcome>* per_seed) {
  LMB_CHECK((calibration != nullptr) == !sweep.calibrated_localized.empty(),
            "sweep_frame_pose: a calibration must be given exactly when the sweep was started calibrated");
  PoseEstimatorOptions o = options;
  const bool budget_swept =
      std::find(sweep.iterations.begin(), sweep.iterations.end(), options.max_iterations) != sweep.iterations.end();
  if (per_seed != nullptr) {
    per_seed->clear();
    for (uint64_t seed : sweep.seeds) {
      if (budget_swept) break;  // filled below, from the sweep's own poses
      o.seed = seed;
      per_seed->push_back(estimate_frame_pose(query, input, o));
    }
  }
  for (size_t b = 0; b < sweep.iterations.size(); ++b) {
    for (size_t s = 0; s < sweep.seeds.size(); ++s) {
      o.max_iterations = sweep.iterations[b];
      o.seed = sweep.seeds[s];
      const FrameOutcome f = estimate_frame_pose(query, input, o);
      if (per_seed != nullptr && budget_swept && o.max_iterations == options.max_iterations &&
          per_seed->size() < sweep.seeds.size()) {
        per_seed->push_back(f);
      }
      const bool right = f.localized && pose_within(f.cam_from_world, f.true_cam_from_world, thresholds);
      sweep.frames_correct[b][s] += right;
      sweep.frames_localized[b][s] += f.localized;
      if (calibration != nullptr && f.localized && calibration->probability(f.evidence) >= calibration->threshold) {
        ++sweep.calibrated_localized[b][s];
        sweep.calibrated_correct[b][s] += right;
      }
    }
  }
  ++sweep.num_frames;
}

}  // namespace lmb
