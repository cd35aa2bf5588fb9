#include "train/mapping/triangulation.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opengv/relative_pose/CentralRelativeAdapter.hpp>
#include <opengv/triangulation/methods.hpp>

#include "common/error.h"

namespace lmb {

void TriangulationOptions::check() const {
  LMB_CHECK(max_reprojection_error_px > 0, "triangulation options: max_reprojection_error_px must be positive");
  LMB_CHECK(min_triangulation_angle_deg >= 0 && min_triangulation_angle_deg < 90,
            "triangulation options: min_triangulation_angle_deg must be in [0, 90)");
  LMB_CHECK(max_pair_hypotheses >= 1, "triangulation options: max_pair_hypotheses must be >= 1");
  LMB_CHECK(refine_iterations >= 0, "triangulation options: refine_iterations must be >= 0");
}

double reprojection_error_px(const TrackObservation& observation, const Eigen::Vector3d& point_in_world) {
  const Eigen::Vector3d p = observation.cam_from_world * point_in_world;
  Eigen::Vector2d pixel;
  if (p.z() <= 1e-9 || !observation.camera->project(p, &pixel)) return std::numeric_limits<double>::infinity();
  const double e = (pixel - observation.pixel).norm();
  return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
}

namespace {

struct Ray {
  Eigen::Vector3d center;      // world
  Eigen::Vector3d direction;   // world, unit
  Eigen::Vector2d normalized;  // undistorted normalized observation
  double focal;
};

// Gauss-Newton on the normalized-plane residuals scaled by focal length (≈ pixels).
Eigen::Vector3d refine(const std::vector<TrackObservation>& obs, const std::vector<Ray>& rays,
                       const std::vector<bool>& use, Eigen::Vector3d x, int iterations) {
  for (int it = 0; it < iterations; ++it) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < obs.size(); ++i) {
      if (!use[i]) continue;
      const Eigen::Matrix3d R = obs[i].cam_from_world.rotation.toRotationMatrix();
      const Eigen::Vector3d p = R * x + obs[i].cam_from_world.translation;
      if (p.z() <= 1e-9) continue;
      const double iz = 1.0 / p.z();
      const Eigen::Vector2d r = rays[i].focal * (Eigen::Vector2d(p.x() * iz, p.y() * iz) - rays[i].normalized);
      Eigen::Matrix<double, 2, 3> dproj;
      dproj << iz, 0, -p.x() * iz * iz, 0, iz, -p.y() * iz * iz;
      const Eigen::Matrix<double, 2, 3> J = rays[i].focal * dproj * R;
      H += J.transpose() * J;
      g += J.transpose() * r;
    }
    const Eigen::Vector3d step = H.ldlt().solve(-g);
    if (!step.allFinite()) break;
    x += step;
    if (step.norm() < 1e-10 * (1.0 + x.norm())) break;
  }
  return x;
}

double max_ray_angle_deg(const std::vector<Ray>& rays, const std::vector<bool>& use, const Eigen::Vector3d& x) {
  double best_cos = 1.0;
  std::vector<Eigen::Vector3d> dirs;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (use[i]) dirs.push_back((x - rays[i].center).normalized());
  }
  for (size_t i = 0; i < dirs.size(); ++i) {
    for (size_t j = i + 1; j < dirs.size(); ++j) best_cos = std::min(best_cos, dirs[i].dot(dirs[j]));
  }
  return std::acos(std::clamp(best_cos, -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace

TriangulatedPoint triangulate_track(const std::vector<TrackObservation>& observations,
                                    const TriangulationOptions& options) {
  TriangulatedPoint result;
  const size_t n = observations.size();
  result.inlier.assign(n, false);
  if (n < 2) return result;
  std::vector<Ray> rays(n);
  for (size_t i = 0; i < n; ++i) {
    const TrackObservation& o = observations[i];
    rays[i].center = o.cam_from_world.center();
    rays[i].normalized = o.camera->cam_from_img(o.pixel);
    rays[i].direction =
        (o.cam_from_world.rotation.conjugate() * Eigen::Vector3d(rays[i].normalized.x(), rays[i].normalized.y(), 1.0))
            .normalized();
    rays[i].focal = o.camera->mean_focal_length();
  }
  // Candidate pairs for two-view hypotheses, widest ray angle first.
  struct PairCandidate {
    double cos_angle;
    int i, j;
  };
  std::vector<PairCandidate> pairs;
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) {
      pairs.push_back({rays[i].direction.dot(rays[j].direction), static_cast<int>(i), static_cast<int>(j)});
    }
  }
  const size_t num_hypotheses = std::min(pairs.size(), static_cast<size_t>(options.max_pair_hypotheses));
  std::partial_sort(pairs.begin(), pairs.begin() + num_hypotheses, pairs.end(),
                    [](const PairCandidate& a, const PairCandidate& b) {
                      if (a.cos_angle != b.cos_angle) return a.cos_angle < b.cos_angle;
                      return a.i != b.i ? a.i < b.i : a.j < b.j;
                    });

  int best_inliers = 0;
  double best_error = std::numeric_limits<double>::infinity();
  Eigen::Vector3d best_point = Eigen::Vector3d::Zero();
  for (size_t h = 0; h < num_hypotheses; ++h) {
    const int i = pairs[h].i, j = pairs[h].j;
    // OpenGV: viewpoint 1 = observation i, viewpoint 2 = observation j; R12, t12 give camera 2 in
    // camera 1's frame; the point comes back in camera 1's frame.
    const Rigid3d cam1_from_cam2 = observations[i].cam_from_world * observations[j].cam_from_world.inverse();
    opengv::bearingVectors_t b1{Eigen::Vector3d(rays[i].normalized.x(), rays[i].normalized.y(), 1.0).normalized()};
    opengv::bearingVectors_t b2{Eigen::Vector3d(rays[j].normalized.x(), rays[j].normalized.y(), 1.0).normalized()};
    opengv::relative_pose::CentralRelativeAdapter adapter(b1, b2, cam1_from_cam2.translation,
                                                          cam1_from_cam2.rotation.toRotationMatrix());
    const Eigen::Vector3d point_in_cam1 = opengv::triangulation::triangulate2(adapter, 0);
    if (!point_in_cam1.allFinite() || point_in_cam1.z() <= 0) continue;
    const Eigen::Vector3d x = observations[i].cam_from_world.inverse() * point_in_cam1;
    int inliers = 0;
    double error_sum = 0;
    for (size_t k = 0; k < n; ++k) {
      const double e = reprojection_error_px(observations[k], x);
      if (e < options.max_reprojection_error_px) {
        ++inliers;
        error_sum += e;
      }
    }
    if (inliers > best_inliers || (inliers == best_inliers && inliers > 0 && error_sum < best_error)) {
      best_inliers = inliers;
      best_error = error_sum;
      best_point = x;
    }
  }
  if (best_inliers < 2) return result;

  // Refine on inliers; re-select inliers; repeat until stable.
  Eigen::Vector3d x = best_point;
  std::vector<bool> inlier(n, false);
  for (size_t k = 0; k < n; ++k)
    inlier[k] = reprojection_error_px(observations[k], x) < options.max_reprojection_error_px;
  for (int round = 0; round < 4; ++round) {
    const Eigen::Vector3d refined = refine(observations, rays, inlier, x, options.refine_iterations);
    std::vector<bool> next(n, false);
    int count = 0;
    for (size_t k = 0; k < n; ++k) {
      next[k] = reprojection_error_px(observations[k], refined) < options.max_reprojection_error_px;
      count += next[k] ? 1 : 0;
    }
    if (count < 2) break;  // keep the unrefined hypothesis
    x = refined;
    const bool stable = next == inlier;
    inlier = next;
    if (stable) break;
  }
  double error_sum = 0;
  int count = 0;
  for (size_t k = 0; k < n; ++k) {
    if (!inlier[k]) continue;
    const double e = reprojection_error_px(observations[k], x);
    if (!(e < options.max_reprojection_error_px)) {
      inlier[k] = false;
      continue;
    }
    error_sum += e;
    ++count;
  }
  result.position = x;
  result.inlier = inlier;
  result.num_inliers = count;
  result.mean_reprojection_error_px = count > 0 ? error_sum / count : 0.0;
  result.triangulation_angle_deg = count >= 2 ? max_ray_angle_deg(rays, inlier, x) : 0.0;
  result.success = count >= 2 && x.allFinite() && result.triangulation_angle_deg >= options.min_triangulation_angle_deg;
  return result;
}

}  // namespace lmb
