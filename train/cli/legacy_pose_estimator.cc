#include "train/cli/legacy_pose_estimator.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>

#include <Eigen/Geometry>
#include <opengv/absolute_pose/CentralAbsoluteAdapter.hpp>
#include <opengv/sac/Ransac.hpp>
#include <opengv/sac_problems/absolute_pose/AbsolutePoseSacProblem.hpp>

#include "common/error.h"
#include "common/random.h"
#include "infer/pose_refine.h"

namespace lmb::legacy {

namespace detail {
namespace {

using OpenGvProblem = opengv::sac_problems::absolute_pose::AbsolutePoseSacProblem;

// KNEIP samples 4 correspondences: P3P on three, the fourth picks among P3P's solutions.
constexpr int kMinSampleSize = 4;
// Refinement: at most this many Levenberg-Marquardt steps, to this relative tolerance.
constexpr int kRefineIterations = 50;
constexpr double kRefineTolerance = 1e-12;
constexpr int kMaxRefineRounds = 4;

// OpenGV's absolute-pose problem with two changes.
// - Seeded sampling. OpenGV samples with a std::mt19937 seeded from time() + clock() (or the
//   constant 12345), drawn through the public std::function rng_gen_ (which holds its own copy of
//   the engine, so reseeding rng_alg_ would not help). The constructor replaces rng_gen_ by
//   lmb::Rng(seed); rnd() must return a non-negative int: 31 random bits.
// - Fast scoring. OpenGV scores every correspondence of every hypothesis through virtual adapter
//   calls returning matrices by value (about 50 ns per correspondence here); this scores from the
//   arrays directly, with the same distance 1 - cos(angle).
class SeededAbsolutePoseProblem : public OpenGvProblem {
 public:
  SeededAbsolutePoseProblem(opengv::absolute_pose::CentralAbsoluteAdapter& adapter,
                            const opengv::bearingVectors_t& bearings, const opengv::points_t& points,
                            const std::vector<int>& indices, uint64_t seed)
      : OpenGvProblem(adapter, OpenGvProblem::KNEIP, indices, /*randomSeed=*/false),
        bearings_(bearings),
        points_(points) {
    rng_gen_ = std::make_shared<std::function<int()>>(
        [rng = Rng(seed)]() mutable { return static_cast<int>(rng.next() >> 33); });
  }

  // 1 - cos of the angle between bearing i and the direction to point i under world_from_cam.
  static double distance(const Eigen::Matrix3d& cam_from_world_rotation, const Eigen::Vector3d& camera_center,
                         const Eigen::Vector3d& point, const Eigen::Vector3d& bearing) {
    const Eigen::Vector3d x = cam_from_world_rotation * (point - camera_center);
    return 1.0 - x.dot(bearing) / x.norm();
  }

  void getSelectedDistancesToModel(const model_t& model, const std::vector<int>& indices,
                                   std::vector<double>& scores) const override {
    const Eigen::Matrix3d rotation = model.leftCols<3>().transpose();
    const Eigen::Vector3d center = model.col(3);
    scores.resize(indices.size());
    for (size_t k = 0; k < indices.size(); ++k) {
      scores[k] = distance(rotation, center, points_[indices[k]], bearings_[indices[k]]);
    }
  }

  int countWithinDistance(const model_t& model, double threshold) override {
    const Eigen::Matrix3d rotation = model.leftCols<3>().transpose();
    const Eigen::Vector3d center = model.col(3);
    int count = 0;
    for (const int i : *indices_) {
      count += distance(rotation, center, points_[i], bearings_[i]) < threshold;
    }
    return count;
  }

 private:
  const opengv::bearingVectors_t& bearings_;
  const opengv::points_t& points_;
};
using SacProblem = SeededAbsolutePoseProblem;

// MSAC cost of a model over the valid correspondences: sum of min(distance, threshold), where
// distance is OpenGV's 1 - cos(angle).
double truncated_cost(const SacProblem& problem, const opengv::transformation_t& model, const std::vector<int>& indices,
                      double threshold) {
  std::vector<double> distances;
  distances.reserve(indices.size());
  problem.getSelectedDistancesToModel(model, indices, distances);
  double cost = 0.0;
  for (const double d : distances) cost += std::isfinite(d) ? std::min(d, threshold) : threshold;
  return cost;
}

// OpenGV's model is world_from_cam: [R | c] with R the camera's axes in the world and c its centre.
Rigid3d cam_from_world_of(const opengv::transformation_t& world_from_cam) {
  const Eigen::Matrix3d cam_from_world_rotation = world_from_cam.leftCols<3>().transpose();
  Eigen::Quaterniond q(cam_from_world_rotation);
  q.normalize();
  return Rigid3d(q, -(cam_from_world_rotation * world_from_cam.col(3)));
}

}  // namespace
}  // namespace detail

LegacyPoseResult estimate_absolute_pose(const Camera& camera, const std::vector<Eigen::Vector2d>& pixels,
                                        const std::vector<Eigen::Vector3d>& points_world,
                                        const LegacyPoseOptions& options) {
  camera.check("estimate_absolute_pose: camera");
  LMB_CHECK(pixels.size() == points_world.size(),
            "estimate_absolute_pose: " << pixels.size() << " pixels but " << points_world.size()
                                       << " world points; they must correspond one to one");
  const size_t n = pixels.size();
  for (size_t i = 0; i < n; ++i) {
    LMB_CHECK(pixels[i].allFinite(),
              "estimate_absolute_pose: pixel " << i << " is not finite (" << pixels[i].transpose() << ")");
    LMB_CHECK(points_world[i].allFinite(),
              "estimate_absolute_pose: world point " << i << " is not finite (" << points_world[i].transpose() << ")");
  }

  LegacyPoseResult result;
  if (n < static_cast<size_t>(detail::kMinSampleSize)) return result;

  // Bearing vectors; a pixel whose undistortion does not converge to a finite point takes no part.
  opengv::bearingVectors_t bearings(n);
  opengv::points_t points(n);
  std::vector<int> valid;
  valid.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d normalized = camera.cam_from_img(pixels[i]);
    bearings[i] = Eigen::Vector3d(normalized.x(), normalized.y(), 1.0).normalized();
    points[i] = points_world[i];
    if (bearings[i].allFinite()) valid.push_back(static_cast<int>(i));
  }
  if (valid.size() < static_cast<size_t>(detail::kMinSampleSize)) return result;

  const double threshold_angle = std::atan(options.max_reprojection_error_px / camera.mean_focal_length());
  const double threshold = 1.0 - std::cos(threshold_angle);
  const double loss_scale = 0.5 * threshold_angle;

  opengv::absolute_pose::CentralAbsoluteAdapter adapter(bearings, points);
  auto problem = std::make_shared<detail::SacProblem>(adapter, bearings, points, valid, options.seed);

  // OpenGV's loop stops once its counter exceeds maxIterations, i.e. after maxIterations + 1
  // hypotheses: pass one less. It also gives up after 10 * maxIterations failed P3P samples, so
  // maxIterations must be at least 1.
  opengv::sac::Ransac<detail::SacProblem> ransac(std::max(options.max_iterations - 1, 1), threshold,
                                                 options.confidence);
  ransac.sac_model_ = problem;
  const bool found = ransac.computeModel(0);
  result.iterations = ransac.iterations_;
  if (!found || !ransac.model_coefficients_.allFinite()) return result;

  opengv::transformation_t model = ransac.model_coefficients_;
  std::vector<int> inliers = ransac.inliers_;
  if (options.refine) {
    double cost = detail::truncated_cost(*problem, model, valid, threshold);
    for (int round = 0; round < detail::kMaxRefineRounds; ++round) {
      if (inliers.size() < static_cast<size_t>(detail::kMinSampleSize)) break;
      const Eigen::Matrix3d cam_from_world_rotation = model.leftCols<3>().transpose();
      // The refinement inference uses, with this estimator's own budget and tolerance.
      const CameraPose r = lmb::detail::refine_cam_from_world(
          bearings.data(), points.data(), inliers,
          CameraPose{cam_from_world_rotation, -(cam_from_world_rotation * model.col(3))}, loss_scale,
          detail::kRefineIterations, detail::kRefineTolerance);
      opengv::transformation_t refined;
      refined.leftCols<3>() = r.rotation.transpose();
      refined.col(3) = -(r.rotation.transpose() * r.translation);
      if (!refined.allFinite()) break;
      const double refined_cost = detail::truncated_cost(*problem, refined, valid, threshold);
      if (!(refined_cost <= cost)) break;
      std::vector<int> refined_inliers;
      problem->selectWithinDistance(refined, threshold, refined_inliers);
      const bool unchanged = refined_inliers == inliers;
      model = refined;
      cost = refined_cost;
      inliers = std::move(refined_inliers);
      if (unchanged) break;
    }
  }

  result.cam_from_world = detail::cam_from_world_of(model);
  result.num_inliers = static_cast<int>(inliers.size());
  result.success = result.num_inliers >= options.min_inliers &&
                   lmb::detail::count_distinct_points(points_world, inliers) >= detail::kMinSampleSize;
  return result;
}

}  // namespace lmb::legacy
