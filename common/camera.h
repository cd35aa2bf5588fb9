// Camera models with COLMAP's definitions and parameter orders, so that COLMAP sparse models read
// and write without conversion. Image coordinates are pixels with COLMAP's convention (the centre of
// the top-left pixel is (0.5, 0.5)); "normalized" coordinates are the undistorted image plane at
// depth 1 (x/z, y/z in the camera frame: x right, y down, z forward).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace lmb {

enum class CameraModel : int {
  kSimplePinhole = 0,  // f, cx, cy
  kPinhole = 1,        // fx, fy, cx, cy
  kSimpleRadial = 2,   // f, cx, cy, k
  kRadial = 3,         // f, cx, cy, k1, k2
  kOpenCV = 4,         // fx, fy, cx, cy, k1, k2, p1, p2
  kFullOpenCV = 6,     // fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6
};

// COLMAP's model name ("PINHOLE", ...) and id; throw lmb::Error for models this project does not
// represent (fisheye models, FOV, THIN_PRISM_FISHEYE). The name's error is prefixed by `where`
// (the file and line, or the flag, it comes from).
CameraModel camera_model_from_name(const std::string& name, const std::string& where);
CameraModel camera_model_from_id(int colmap_id);
std::string camera_model_name(CameraModel model);
int camera_model_num_params(CameraModel model);

struct Camera {
  CameraModel model = CameraModel::kPinhole;
  int width = 0;
  int height = 0;
  std::vector<double> params;

  // Throws lmb::Error when the parameter count, sizes or values (NaN, non-positive focal length)
  // are invalid. `where` prefixes the message (e.g. "cameras.txt line 4").
  void check(const std::string& where = "camera") const;

  double mean_focal_length() const;
  Eigen::Vector2d principal_point() const;

  // Pixel of a normalized undistorted point (applies the lens distortion).
  Eigen::Vector2d img_from_cam(const Eigen::Vector2d& normalized) const;
  // Normalized undistorted point of a pixel (iterative undistortion, COLMAP's method).
  Eigen::Vector2d cam_from_img(const Eigen::Vector2d& pixel) const;
  // Projects a 3D point in the camera frame; returns false behind the camera.
  bool project(const Eigen::Vector3d& point_in_cam, Eigen::Vector2d* pixel) const;

  bool has_distortion() const;
  // Distortion offset of a normalized point, COLMAP's Distortion(): distorted = u + du.
  Eigen::Vector2d distortion(const Eigen::Vector2d& normalized) const;
};

// A camera from the text of a COLMAP cameras.txt line without its id: "MODEL WIDTH HEIGHT
// PARAMS..." separated by white space, e.g. "PINHOLE 640 480 525 525 319.5 239.5" (a leading
// integer CAMERA_ID, as in a line copied from cameras.txt, is skipped). Throws lmb::Error "<where>:
// <reason>": an unsupported model, a width or height that is not a positive integer, a parameter
// that is not a finite number, the wrong parameter count (Camera::check).
Camera camera_from_text(const std::string& text, const std::string& where);
// The inverse: "MODEL WIDTH HEIGHT PARAMS..." with every parameter as the text that parses back to
// the same double ("%.17g").
std::string camera_to_text(const Camera& camera);

}  // namespace lmb
