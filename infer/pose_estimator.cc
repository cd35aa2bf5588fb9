#include "infer/pose_estimator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "common/error.h"
#include "infer/p3p.h"
#include "infer/pose_refine.h"

namespace lmb {

namespace detail {
namespace {

constexpr int kMinPoints = 4;
// Local optimisation budgets: inside the loop (LO) a few Levenberg-Marquardt steps and inlier
// re-selections rank a hypothesis; the answer's final refinement runs to convergence.
constexpr int kLoRounds = 2;
constexpr int kLoIterations = 8;
constexpr int kFinalRounds = 4;
constexpr int kFinalIterations = 50;

}  // namespace

CameraPose refine_cam_from_world(const Eigen::Vector3d* bearings, const Eigen::Vector3d* points,
                                 const std::vector<int>& indices, const CameraPose& start, double scale,
                                 int max_iterations, double tolerance) {
  const size_t m = indices.size();
  // Tangent-plane bases of the observed bearings.
  std::vector<Eigen::Matrix<double, 2, 3>> tangent(m);
  for (size_t k = 0; k < m; ++k) {
    const Eigen::Vector3d& b = bearings[indices[k]];
    const Eigen::Vector3d e1 = b.unitOrthogonal();
    tangent[k].row(0) = e1.transpose();
    tangent[k].row(1) = b.cross(e1).transpose();
  }
  const double scale2 = scale * scale;
  auto cost_of = [&](const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation) {
    double cost = 0;
    for (size_t k = 0; k < m; ++k) {
      const Eigen::Vector3d x = rotation * points[indices[k]] + translation;
      const double r2 = (tangent[k] * x.normalized()).squaredNorm();
      // A point behind the camera gets the largest residual the loss allows for |r| = 1.
      cost += std::log1p((x.dot(bearings[indices[k]]) > 0 ? r2 : 1.0) / scale2);
    }
    return cost;
  };

  CameraPose best = start;
  double best_cost = cost_of(best.rotation, best.translation);
  double lambda = 1e-3;
  for (int it = 0; it < max_iterations; ++it) {
    // Normal equations of the IRLS-weighted Gauss-Newton step for the left perturbation
    // R <- exp(w) R, t <- t + v, unknowns (w, v).
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    for (size_t k = 0; k < m; ++k) {
      const Eigen::Vector3d rx = best.rotation * points[indices[k]];
      const Eigen::Vector3d x = rx + best.translation;
      const double norm = x.norm();
      const Eigen::Vector3d d = x / norm;
      const Eigen::Vector2d r = tangent[k] * d;
      const double weight = 1.0 / (1.0 + r.squaredNorm() / scale2);
      Eigen::Matrix<double, 3, 6> dx;
      dx.leftCols<3>() << 0, rx.z(), -rx.y(), -rx.z(), 0, rx.x(), rx.y(), -rx.x(), 0;  // -[Rx]_x
      dx.rightCols<3>().setIdentity();
      const Eigen::Matrix<double, 2, 6> J =
          tangent[k] * ((Eigen::Matrix3d::Identity() - d * d.transpose()) / norm) * dx;
      H.noalias() += weight * J.transpose() * J;
      g.noalias() += weight * J.transpose() * r;
    }
    bool improved = false;
    while (lambda < 1e10) {
      Eigen::Matrix<double, 6, 6> damped = H;
      damped.diagonal() += lambda * H.diagonal().cwiseMax(1e-12);
      const Eigen::Matrix<double, 6, 1> step = -damped.ldlt().solve(g);
      if (!step.allFinite()) break;
      CameraPose candidate;
      const double angle = step.head<3>().norm();
      candidate.rotation = (angle > 0 ? Eigen::AngleAxisd(angle, step.head<3>() / angle).toRotationMatrix()
                                      : Eigen::Matrix3d::Identity()) *
                           best.rotation;
      candidate.translation = best.translation + step.tail<3>();
      const double cost = cost_of(candidate.rotation, candidate.translation);
      if (cost < best_cost) {
        const bool converged =
            step.norm() < tolerance * (1.0 + best.translation.norm()) || best_cost - cost < tolerance * best_cost;
        best = candidate;
        best_cost = cost;
        lambda = std::max(lambda * 0.1, 1e-12);
        improved = !converged;
        break;
      }
      lambda *= 10;
    }
    if (!improved) break;
  }
  return best;
}

int count_distinct_points(const std::vector<Eigen::Vector3d>& points, const std::vector<int>& inliers) {
  std::vector<std::array<double, 3>> distinct;
  distinct.reserve(inliers.size());
  for (const int i : inliers) distinct.push_back({points[i].x(), points[i].y(), points[i].z()});
  std::sort(distinct.begin(), distinct.end());
  return static_cast<int>(std::unique(distinct.begin(), distinct.end()) - distinct.begin());
}

namespace {

Rigid3d rigid_of(const CameraPose& pose) {
  Eigen::Quaterniond q(pose.rotation);
  q.normalize();
  return Rigid3d(q, pose.translation);
}

}  // namespace

// The ransac<> estimator of the absolute pose: bearing vectors <-> world points, P3P, angular
// residuals 1 - cos(angle) against `threshold`, LO by refine_cam_from_world.
class AbsolutePoseEstimator {
 public:
  using Model = CameraPose;
  static constexpr int kSampleSize = 3;

  AbsolutePoseEstimator(const std::vector<Eigen::Vector3d>& bearings, const std::vector<Eigen::Vector3d>& points,
                        double threshold, double loss_scale, bool refine)
      : bearings_(bearings),
        points_(points),
        threshold_(threshold),
        min_cos_(1.0 - threshold),
        loss_scale_(loss_scale),
        refine_(refine) {}

  int num_data() const { return static_cast<int>(bearings_.size()); }

  void generate_models(const int* sample, std::vector<CameraPose>* models) {
    const Eigen::Vector3d b[3] = {bearings_[sample[0]], bearings_[sample[1]], bearings_[sample[2]]};
    const Eigen::Vector3d p[3] = {points_[sample[0]], points_[sample[1]], points_[sample[2]]};
    const size_t first = models->size();
    p3p(b, p, models);
    // Kneip's quartic also yields poses that put a sample point behind the camera or that do not
    // reproduce its bearing (numerically poor roots): such a model cannot be the pose of an
    // all-inlier sample, so it is dropped before scoring.
    const double c2 = min_cos_ * min_cos_;
    size_t kept = first;
    for (size_t k = first; k < models->size(); ++k) {
      const CameraPose& model = (*models)[k];
      bool consistent = true;
      for (int j = 0; j < 3 && consistent; ++j) {
        const Eigen::Vector3d x = model.rotation * p[j] + model.translation;
        const double d = x.dot(b[j]);
        consistent = d > 0 && d * d > c2 * x.squaredNorm();
      }
      if (consistent) (*models)[kept++] = model;
    }
    models->resize(kept);
  }

  // Residual 1 - cos(angle) is below the threshold exactly when x.b > 0 and
  // (x.b)^2 > (1 - threshold)^2 |x|^2; only inliers need the square root.
  double score(const CameraPose& model, int* num_inliers) const {
    const Eigen::Matrix3d& R = model.rotation;
    const Eigen::Vector3d& t = model.translation;
    const double c2 = min_cos_ * min_cos_;
    double cost = 0.0;
    int inliers = 0;
    const size_t n = bearings_.size();
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d x = R * points_[i] + t;
      const double d = x.dot(bearings_[i]);
      const double x2 = x.squaredNorm();
      if (d > 0 && d * d > c2 * x2) {
        cost += 1.0 - d / std::sqrt(x2);
        ++inliers;
      } else {
        cost += threshold_;
      }
    }
    *num_inliers = inliers;
    return cost;
  }

  void inliers(const CameraPose& model, std::vector<char>* mask) const {
    const double c2 = min_cos_ * min_cos_;
    const size_t n = bearings_.size();
    mask->resize(n);
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d x = model.rotation * points_[i] + model.translation;
      const double d = x.dot(bearings_[i]);
      (*mask)[i] = d > 0 && d * d > c2 * x.squaredNorm();
    }
  }

  void refine(CameraPose* model, bool final) const {
    if (!refine_) return;
    const int rounds = final ? kFinalRounds : kLoRounds;
    const int iterations = final ? kFinalIterations : kLoIterations;
    std::vector<char> mask;
    inliers(*model, &mask);
    std::vector<int> indices = indices_of(mask);
    int count = 0;
    double cost = score(*model, &count);
    for (int round = 0; round < rounds; ++round) {
      if (indices.size() < static_cast<size_t>(kMinPoints)) break;
      const CameraPose refined =
          refine_cam_from_world(bearings_.data(), points_.data(), indices, *model, loss_scale_, iterations);
      if (!refined.rotation.allFinite() || !refined.translation.allFinite()) break;
      const double refined_cost = score(refined, &count);
      if (!(refined_cost <= cost)) break;
      inliers(refined, &mask);
      std::vector<int> refined_indices = indices_of(mask);
      const bool unchanged = refined_indices == indices;
      *model = refined;
      cost = refined_cost;
      indices = std::move(refined_indices);
      if (unchanged) break;
    }
  }

 private:
  static std::vector<int> indices_of(const std::vector<char>& mask) {
    std::vector<int> indices;
    for (size_t i = 0; i < mask.size(); ++i) {
      if (mask[i]) indices.push_back(static_cast<int>(i));
    }
    return indices;
  }

  const std::vector<Eigen::Vector3d>& bearings_;
  const std::vector<Eigen::Vector3d>& points_;
  double threshold_;
  double min_cos_;
  double loss_scale_;
  bool refine_;
};

}  // namespace detail

void PoseEstimatorOptions::check() const {
  LMB_CHECK(max_iterations >= 1, "PoseEstimatorOptions.max_iterations must be >= 1, got " << max_iterations);
  LMB_CHECK(min_iterations >= 0 && min_iterations <= max_iterations,
            "PoseEstimatorOptions.min_iterations must be in 0..max_iterations (" << max_iterations << "), got "
                                                                                 << min_iterations);
  LMB_CHECK(std::isfinite(max_reprojection_error_px) && max_reprojection_error_px > 0,
            "PoseEstimatorOptions.max_reprojection_error_px must be a positive number of pixels, got "
                << max_reprojection_error_px);
  LMB_CHECK(success_probability > 0 && success_probability < 1,
            "PoseEstimatorOptions.success_probability must be in (0, 1), got " << success_probability);
  LMB_CHECK(min_inliers >= detail::kMinPoints,
            "PoseEstimatorOptions.min_inliers must be >= " << detail::kMinPoints << ", got " << min_inliers);
}

PoseResult estimate_absolute_pose(const Camera& camera, const std::vector<Eigen::Vector2d>& pixels,
                                  const std::vector<Eigen::Vector3d>& points_world, const PoseEstimatorOptions& options,
                                  const std::vector<double>& quality) {
  options.check();
  camera.check("estimate_absolute_pose: camera");
  LMB_CHECK(pixels.size() == points_world.size(),
            "estimate_absolute_pose: " << pixels.size() << " pixels but " << points_world.size()
                                       << " world points; they must correspond one to one");
  LMB_CHECK(quality.empty() || quality.size() == pixels.size(),
            "estimate_absolute_pose: " << quality.size() << " quality values for " << pixels.size()
                                       << " correspondences (give one each, or none)");
  const size_t n = pixels.size();
  for (size_t i = 0; i < n; ++i) {
    LMB_CHECK(pixels[i].allFinite(),
              "estimate_absolute_pose: pixel " << i << " is not finite (" << pixels[i].transpose() << ")");
    LMB_CHECK(points_world[i].allFinite(),
              "estimate_absolute_pose: world point " << i << " is not finite (" << points_world[i].transpose() << ")");
    LMB_CHECK(quality.empty() || std::isfinite(quality[i]),
              "estimate_absolute_pose: quality " << i << " is not finite (" << quality[i] << ")");
  }

  PoseResult result;
  result.inlier_mask.assign(n, 0);

  // The usable correspondences (a pixel whose undistortion does not converge to a finite point
  // takes no part), in sampling order: decreasing quality, ties in input order.
  std::vector<int> order;
  order.reserve(n);
  const std::vector<Eigen::Vector3d> all_bearings = keypoint_bearings(camera, pixels);
  for (size_t i = 0; i < n; ++i) {
    if (all_bearings[i].allFinite()) order.push_back(static_cast<int>(i));
  }
  const bool progressive = options.progressive_sampling && !quality.empty();
  if (progressive) {
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return quality[a] > quality[b]; });
  }
  result.stats.num_data = static_cast<int>(order.size());
  result.stats.subset_size = static_cast<int>(order.size());
  if (order.size() < static_cast<size_t>(detail::kMinPoints)) return result;
  std::vector<Eigen::Vector3d> bearings, points;
  bearings.reserve(order.size());
  points.reserve(order.size());
  for (const int i : order) {
    bearings.push_back(all_bearings[i]);
    points.push_back(points_world[i]);
  }

  const double threshold_angle = std::atan(options.max_reprojection_error_px / camera.mean_focal_length());
  const double threshold = 1.0 - std::cos(threshold_angle);
  detail::AbsolutePoseEstimator estimator(bearings, points, threshold, 0.5 * threshold_angle, options.refine);

  RansacOptions ro;
  ro.max_iterations = options.max_iterations;
  ro.min_iterations = options.min_iterations;
  ro.success_probability = options.success_probability;
  ro.progressive = progressive;
  ro.seed = options.seed;
  ro.min_support = options.min_inliers;
  const double image_area = static_cast<double>(camera.width) * camera.height;
  ro.random_inlier_probability =
      std::clamp(M_PI * options.max_reprojection_error_px * options.max_reprojection_error_px / image_area, 1e-6, 0.5);

  CameraPose best, runner_up;
  result.stats = ransac(estimator, ro, &best, &runner_up);
  result.iterations = result.stats.iterations;
  if (result.stats.num_inliers == 0) return result;

  std::vector<char> mask;
  estimator.inliers(best, &mask);
  std::vector<int> inliers;
  for (size_t k = 0; k < mask.size(); ++k) {
    if (mask[k]) {
      result.inlier_mask[order[k]] = 1;
      inliers.push_back(order[k]);
    }
  }
  result.cam_from_world = detail::rigid_of(best);
  result.num_inliers = static_cast<int>(inliers.size());
  if (result.stats.runner_up_inliers > 0) result.runner_up_cam_from_world = detail::rigid_of(runner_up);
  result.success = result.num_inliers >= options.min_inliers &&
                   detail::count_distinct_points(points_world, inliers) >= detail::kMinPoints;
  return result;
}

std::vector<Eigen::Vector3d> keypoint_bearings(const Camera& camera, const std::vector<Eigen::Vector2d>& pixels) {
  std::vector<Eigen::Vector3d> bearings(pixels.size());
  for (size_t k = 0; k < pixels.size(); ++k) {
    const Eigen::Vector2d normalized = camera.cam_from_img(pixels[k]);
    bearings[k] = Eigen::Vector3d(normalized.x(), normalized.y(), 1.0).normalized();
  }
  return bearings;
}

std::vector<int> count_explained_keypoints(const Camera& camera, const std::vector<Eigen::Vector2d>& pixels,
                                           const std::vector<std::vector<Eigen::Vector3d>>& points,
                                           const std::vector<Rigid3d>& cam_from_world, double max_reprojection_error_px,
                                           const Rigid3d* unless_explained_by) {
  LMB_CHECK(points.size() == pixels.size(),
            "count_explained_keypoints: " << points.size() << " point lists for " << pixels.size() << " pixels");
  return count_explained_keypoints(camera, keypoint_bearings(camera, pixels), points, cam_from_world,
                                   max_reprojection_error_px, unless_explained_by);
}

std::vector<int> count_explained_keypoints(const Camera& camera, const std::vector<Eigen::Vector3d>& all_bearings,
                                           const std::vector<std::vector<Eigen::Vector3d>>& points,
                                           const std::vector<Rigid3d>& cam_from_world, double max_reprojection_error_px,
                                           const Rigid3d* unless_explained_by) {
  LMB_CHECK(points.size() == all_bearings.size(), "count_explained_keypoints: " << points.size() << " point lists for "
                                                                                << all_bearings.size() << " bearings");
  LMB_CHECK(std::isfinite(max_reprojection_error_px) && max_reprojection_error_px > 0.0,
            "count_explained_keypoints: max_reprojection_error_px = " << max_reprojection_error_px
                                                                      << " must be finite and > 0");
  // The estimator's test (AbsolutePoseEstimator::score): x.b > 0 and (x.b)^2 > cos^2 |x|^2.
  const double min_cos = std::cos(std::atan(max_reprojection_error_px / camera.mean_focal_length()));
  const double c2 = min_cos * min_cos;
  // The keypoints with candidates and a bearing.
  std::vector<size_t> keypoints;
  std::vector<Eigen::Vector3d> bearings;
  for (size_t k = 0; k < all_bearings.size(); ++k) {
    if (points[k].empty() || !all_bearings[k].allFinite()) continue;
    keypoints.push_back(k);
    bearings.push_back(all_bearings[k]);
  }
  const auto passes = [&](const Eigen::Matrix3d& R, const Eigen::Vector3d& t, const Eigen::Vector3d& p,
                          const Eigen::Vector3d& bearing) {
    const Eigen::Vector3d x = R * p + t;
    const double d = x.dot(bearing);
    return d > 0 && d * d > c2 * x.squaredNorm();
  };
  Eigen::Matrix3d R_ref = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_ref = Eigen::Vector3d::Zero();
  if (unless_explained_by != nullptr) {
    R_ref = unless_explained_by->rotation.toRotationMatrix();
    t_ref = unless_explained_by->translation;
  }
  std::vector<int> explained(cam_from_world.size(), 0);
  for (size_t i = 0; i < cam_from_world.size(); ++i) {
    const Eigen::Matrix3d R = cam_from_world[i].rotation.toRotationMatrix();
    const Eigen::Vector3d& t = cam_from_world[i].translation;
    for (size_t j = 0; j < keypoints.size(); ++j) {
      for (const Eigen::Vector3d& p : points[keypoints[j]]) {
        if (passes(R, t, p, bearings[j]) && (unless_explained_by == nullptr || !passes(R_ref, t_ref, p, bearings[j]))) {
          ++explained[i];
          break;
        }
      }
    }
  }
  return explained;
}

}  // namespace lmb
