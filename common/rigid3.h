// Rigid transforms, named a_from_b: x_a = a_from_b * x_b.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace lmb {

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) : rotation(q), translation(t) {}

  Eigen::Vector3d operator*(const Eigen::Vector3d& x) const { return rotation * x + translation; }
  Rigid3d operator*(const Rigid3d& other) const {
    return Rigid3d(rotation * other.rotation, rotation * other.translation + translation);
  }
  Rigid3d inverse() const {
    const Eigen::Quaterniond q_inv = rotation.conjugate();
    return Rigid3d(q_inv, -(q_inv * translation));
  }
  // Centre of a camera whose pose is cam_from_world, in world coordinates.
  Eigen::Vector3d center() const { return -(rotation.conjugate() * translation); }
};

// Position error (same units as the translation) and rotation error (degrees) between two poses.
inline double position_error(const Rigid3d& a, const Rigid3d& b) { return (a.center() - b.center()).norm(); }
inline double rotation_error_deg(const Rigid3d& a, const Rigid3d& b) {
  return a.rotation.angularDistance(b.rotation) * 180.0 / M_PI;
}

}  // namespace lmb
