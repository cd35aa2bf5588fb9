#include "train/mapping/camera_refinement.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "common/error.h"

namespace lmb {

void CameraRefinementOptions::check() const {
  LMB_CHECK(max_iterations >= 0, "camera refinement options: max_iterations must be >= 0");
  LMB_CHECK(huber_px > 0, "camera refinement options: huber_px must be positive");
  LMB_CHECK(min_observations >= 1, "camera refinement options: min_observations must be >= 1");
}

namespace {

bool single_focal(CameraModel m) {
  return m == CameraModel::kSimplePinhole || m == CameraModel::kSimpleRadial || m == CameraModel::kRadial;
}

// Unknowns of one camera: log focal scale, then (with the principal point) cx and cy shifts.
struct CameraDelta {
  double log_scale = 0;
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();
};

// One observation's residual (predicted - observed pixel) and Jacobians; false behind the camera.
struct Linearized {
  Eigen::Vector2d residual;
  Eigen::Matrix<double, 2, 3> d_point;   // d pixel / d world point
  Eigen::Matrix<double, 2, 3> d_camera;  // d pixel / d (log scale, cx, cy)
};

bool linearize(const Camera& camera, const Rigid3d& cam_from_world, const Eigen::Vector3d& x,
               const Eigen::Vector2d& pixel, Linearized* out) {
  const Eigen::Matrix3d R = cam_from_world.rotation.toRotationMatrix();
  const Eigen::Vector3d p = R * x + cam_from_world.translation;
  if (p.z() <= 1e-9) return false;
  const Eigen::Vector2d n(p.x() / p.z(), p.y() / p.z());
  const Eigen::Vector2d predicted = camera.img_from_cam(n);
  if (!predicted.allFinite()) return false;
  out->residual = predicted - pixel;
  Eigen::Matrix2d d_normalized;  // d pixel / d normalized, central differences (distortion included)
  const double h = 1e-6;
  for (int a = 0; a < 2; ++a) {
    Eigen::Vector2d step = Eigen::Vector2d::Zero();
    step[a] = h;
    d_normalized.col(a) = (camera.img_from_cam(n + step) - camera.img_from_cam(n - step)) / (2 * h);
  }
  Eigen::Matrix<double, 2, 3> d_projection;
  const double iz = 1.0 / p.z();
  d_projection << iz, 0, -p.x() * iz * iz, 0, iz, -p.y() * iz * iz;
  out->d_point = d_normalized * d_projection * R;
  out->d_camera.col(0) = predicted - camera.principal_point();
  out->d_camera.col(1) = Eigen::Vector2d(1, 0);
  out->d_camera.col(2) = Eigen::Vector2d(0, 1);
  return out->residual.allFinite() && out->d_point.allFinite();
}

double huber_weight(double error, double delta) { return error <= delta ? 1.0 : delta / error; }
double huber_cost(double error, double delta) {
  return error <= delta ? 0.5 * error * error : delta * (error - 0.5 * delta);
}

struct Problem {
  const std::vector<Rigid3d>& poses;
  const std::vector<camera_t>& frame_camera;
  const std::vector<RefinementTrack>& tracks;
  const CameraRefinementOptions& options;
  std::vector<bool> free;  // per camera: refined (enough observations)
  int k = 1;               // unknowns per camera
};

// Robust cost and per-camera plain error sums and counts.
double evaluate(const Problem& problem, const std::vector<Camera>& cameras, const std::vector<Eigen::Vector3d>& points,
                std::vector<double>* error_sum, std::vector<int64_t>* count) {
  double cost = 0;
  if (error_sum) error_sum->assign(cameras.size(), 0.0);
  if (count) count->assign(cameras.size(), 0);
  for (size_t t = 0; t < problem.tracks.size(); ++t) {
    const RefinementTrack& track = problem.tracks[t];
    for (size_t o = 0; o < track.frames.size(); ++o) {
      const int f = track.frames[o];
      const camera_t c = problem.frame_camera[f];
      const Eigen::Vector3d p = problem.poses[f] * points[t];
      if (p.z() <= 1e-9) continue;
      const double e =
          (cameras[c].img_from_cam(Eigen::Vector2d(p.x() / p.z(), p.y() / p.z())) - track.pixels[o]).norm();
      if (!std::isfinite(e)) continue;
      cost += huber_cost(e, problem.options.huber_px);
      if (error_sum) (*error_sum)[c] += e;
      if (count) ++(*count)[c];
    }
  }
  return cost;
}

// A track's point block after linearization: its (damped) inverse Hessian, gradient and its
// coupling to each camera it is seen by.
struct TrackBlock {
  Eigen::Matrix3d hpp_inv = Eigen::Matrix3d::Zero();
  Eigen::Vector3d gp = Eigen::Vector3d::Zero();
  std::vector<camera_t> cameras;                       // free cameras seeing the track, unique
  std::vector<Eigen::Matrix<double, 3, 3>> couplings;  // per camera: d_point^T d_camera (first k columns)
};

// Linearizes one track into *block, adding its camera-camera terms to S and b (not yet reduced).
void linearize_track(const Problem& problem, const std::vector<Camera>& cameras, const RefinementTrack& track,
                     const Eigen::Vector3d& point, double lambda, TrackBlock* block, Eigen::MatrixXd* S,
                     Eigen::VectorXd* b) {
  const int k = problem.k;
  Eigen::Matrix3d hpp = Eigen::Matrix3d::Zero();
  block->cameras.clear();
  block->couplings.clear();
  Linearized lin;
  for (size_t o = 0; o < track.frames.size(); ++o) {
    const int f = track.frames[o];
    const camera_t c = problem.frame_camera[f];
    if (!linearize(cameras[c], problem.poses[f], point, track.pixels[o], &lin)) continue;
    const double w = huber_weight(lin.residual.norm(), problem.options.huber_px);
    hpp += w * lin.d_point.transpose() * lin.d_point;
    block->gp += w * lin.d_point.transpose() * lin.residual;
    if (!problem.free[c]) continue;
    const auto jc = lin.d_camera.leftCols(k);
    size_t slot = std::find(block->cameras.begin(), block->cameras.end(), c) - block->cameras.begin();
    if (slot == block->cameras.size()) {
      block->cameras.push_back(c);
      block->couplings.push_back(Eigen::Matrix3d::Zero());
    }
    block->couplings[slot].leftCols(k) += w * lin.d_point.transpose() * jc;
    S->block(c * k, c * k, k, k) += w * jc.transpose() * jc;
    b->segment(c * k, k) += w * jc.transpose() * lin.residual;
  }
  hpp.diagonal() *= 1.0 + lambda;
  Eigen::FullPivLU<Eigen::Matrix3d> lu(hpp);
  if (!lu.isInvertible()) {  // a track without constraints stays where it is
    block->cameras.clear();
    block->couplings.clear();
    block->gp.setZero();
    return;
  }
  block->hpp_inv = lu.inverse();
}

// One damped Gauss-Newton step (points eliminated per track); false when the system is singular.
bool solve_step(const Problem& problem, const std::vector<Camera>& cameras, const std::vector<Eigen::Vector3d>& points,
                double lambda, std::vector<CameraDelta>* camera_step, std::vector<Eigen::Vector3d>* point_step) {
  const int k = problem.k;
  const int dim = static_cast<int>(cameras.size()) * k;
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(dim, dim);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(dim);
  std::vector<TrackBlock> blocks(problem.tracks.size());
  for (size_t t = 0; t < problem.tracks.size(); ++t) {
    TrackBlock& block = blocks[t];
    linearize_track(problem, cameras, problem.tracks[t], points[t], lambda, &block, &S, &b);
    for (size_t u = 0; u < block.cameras.size(); ++u) {
      const auto cu = block.couplings[u].leftCols(k);
      b.segment(block.cameras[u] * k, k) -= cu.transpose() * block.hpp_inv * block.gp;
      for (size_t v = 0; v < block.cameras.size(); ++v) {
        const auto cv = block.couplings[v].leftCols(k);
        S.block(block.cameras[u] * k, block.cameras[v] * k, k, k) -= cu.transpose() * block.hpp_inv * cv;
      }
    }
  }
  for (size_t c = 0; c < cameras.size(); ++c) {
    for (int a = 0; a < k; ++a) {
      const int i = static_cast<int>(c) * k + a;
      if (!problem.free[c]) {
        S.row(i).setZero();
        S.col(i).setZero();
        S(i, i) = 1.0;
        b[i] = 0;
      } else {
        S(i, i) *= 1.0 + lambda;
      }
    }
  }
  const Eigen::VectorXd delta = S.ldlt().solve(-b);
  if (!delta.allFinite()) return false;
  camera_step->assign(cameras.size(), CameraDelta{});
  for (size_t c = 0; c < cameras.size(); ++c) {
    (*camera_step)[c].log_scale = delta[static_cast<int>(c) * k];
    if (k == 3) (*camera_step)[c].shift = delta.segment<2>(static_cast<int>(c) * k + 1);
  }
  point_step->resize(points.size());
  for (size_t t = 0; t < points.size(); ++t) {
    Eigen::Vector3d rhs = blocks[t].gp;
    for (size_t u = 0; u < blocks[t].cameras.size(); ++u) {
      rhs += blocks[t].couplings[u].leftCols(k) * delta.segment(blocks[t].cameras[u] * k, k);
    }
    (*point_step)[t] = -blocks[t].hpp_inv * rhs;
  }
  return true;
}

}  // namespace

Camera scaled_camera(const Camera& camera, double scale, const Eigen::Vector2d& shift) {
  Camera out = camera;
  const bool single = single_focal(camera.model);
  out.params[0] *= scale;
  if (!single) out.params[1] *= scale;
  const size_t pp = single ? 1 : 2;
  out.params[pp] += shift.x();
  out.params[pp + 1] += shift.y();
  return out;
}

CameraRefinementResult refine_cameras(const std::vector<Camera>& cameras, const std::vector<Rigid3d>& cam_from_world,
                                      const std::vector<camera_t>& frame_camera,
                                      const std::vector<RefinementTrack>& tracks,
                                      const CameraRefinementOptions& options) {
  options.check();
  LMB_CHECK(cam_from_world.size() == frame_camera.size(), "camera refinement: poses and frame cameras differ in size");
  for (camera_t c : frame_camera) {
    LMB_CHECK(c >= 0 && c < static_cast<camera_t>(cameras.size()), "camera refinement: camera index out of range");
  }
  for (const RefinementTrack& t : tracks) {
    LMB_CHECK(t.frames.size() == t.pixels.size(), "camera refinement: a track's frames and pixels differ in size");
    for (int f : t.frames) {
      LMB_CHECK(f >= 0 && f < static_cast<int>(frame_camera.size()), "camera refinement: frame index out of range");
    }
  }
  Problem problem{cam_from_world, frame_camera, tracks, options, {}, options.principal_point ? 3 : 1};
  CameraRefinementResult result;
  result.cameras = cameras;
  std::vector<Eigen::Vector3d> points;
  for (const RefinementTrack& t : tracks) points.push_back(t.position);
  std::vector<double> error_sum;
  double cost = evaluate(problem, cameras, points, &error_sum, &result.observations);
  result.mean_error_before_px.resize(cameras.size());
  for (size_t c = 0; c < cameras.size(); ++c) {
    problem.free.push_back(result.observations[c] >= options.min_observations);
    result.mean_error_before_px[c] = error_sum[c] / std::max<double>(1.0, static_cast<double>(result.observations[c]));
  }
  double lambda = 1e-4;
  std::vector<CameraDelta> camera_step;
  std::vector<Eigen::Vector3d> point_step;
  for (int it = 0; it < options.max_iterations; ++it) {
    if (!solve_step(problem, result.cameras, points, lambda, &camera_step, &point_step)) break;
    std::vector<Camera> trial_cameras = result.cameras;
    for (size_t c = 0; c < cameras.size(); ++c) {
      trial_cameras[c] = scaled_camera(result.cameras[c], std::exp(camera_step[c].log_scale), camera_step[c].shift);
    }
    std::vector<Eigen::Vector3d> trial_points = points;
    for (size_t t = 0; t < points.size(); ++t) trial_points[t] += point_step[t];
    const double trial_cost = evaluate(problem, trial_cameras, trial_points, nullptr, nullptr);
    result.iterations = it + 1;
    if (trial_cost < cost) {
      const double gain = cost - trial_cost;
      result.cameras = trial_cameras;
      points = trial_points;
      cost = trial_cost;
      lambda = std::max(lambda / 3.0, 1e-9);
      if (gain < 1e-9 * cost) break;
    } else {
      lambda *= 4.0;
      if (lambda > 1e6) break;
    }
  }
  std::vector<int64_t> count;
  evaluate(problem, result.cameras, points, &error_sum, &count);
  result.mean_error_after_px.resize(cameras.size());
  for (size_t c = 0; c < cameras.size(); ++c) {
    result.mean_error_after_px[c] = error_sum[c] / std::max<double>(1.0, static_cast<double>(count[c]));
  }
  result.positions = std::move(points);
  return result;
}

}  // namespace lmb
