#include "common/camera.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>

#include <Eigen/LU>

#include "common/error.h"
#include "common/text_parse.h"

namespace lmb {

CameraModel camera_model_from_name(const std::string& name, const std::string& where) {
  if (name == "SIMPLE_PINHOLE") return CameraModel::kSimplePinhole;
  if (name == "PINHOLE") return CameraModel::kPinhole;
  if (name == "SIMPLE_RADIAL") return CameraModel::kSimpleRadial;
  if (name == "RADIAL") return CameraModel::kRadial;
  if (name == "OPENCV") return CameraModel::kOpenCV;
  if (name == "FULL_OPENCV") return CameraModel::kFullOpenCV;
  LMB_FAIL(where << ": unsupported camera model '" << name
                 << "' (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV)");
}

CameraModel camera_model_from_id(int colmap_id) {
  switch (colmap_id) {
    case 0: return CameraModel::kSimplePinhole;
    case 1: return CameraModel::kPinhole;
    case 2: return CameraModel::kSimpleRadial;
    case 3: return CameraModel::kRadial;
    case 4: return CameraModel::kOpenCV;
    case 6: return CameraModel::kFullOpenCV;
    default: break;
  }
  LMB_FAIL("unsupported camera model id "
           << colmap_id
           << " (supported COLMAP ids: 0 SIMPLE_PINHOLE, 1 PINHOLE, 2 SIMPLE_RADIAL, 3 RADIAL,"
              " 4 OPENCV, 6 FULL_OPENCV)");
}

std::string camera_model_name(CameraModel model) {
  switch (model) {
    case CameraModel::kSimplePinhole: return "SIMPLE_PINHOLE";
    case CameraModel::kPinhole: return "PINHOLE";
    case CameraModel::kSimpleRadial: return "SIMPLE_RADIAL";
    case CameraModel::kRadial: return "RADIAL";
    case CameraModel::kOpenCV: return "OPENCV";
    case CameraModel::kFullOpenCV: return "FULL_OPENCV";
  }
  return "UNKNOWN";
}

int camera_model_num_params(CameraModel model) {
  switch (model) {
    case CameraModel::kSimplePinhole: return 3;
    case CameraModel::kPinhole: return 4;
    case CameraModel::kSimpleRadial: return 4;
    case CameraModel::kRadial: return 5;
    case CameraModel::kOpenCV: return 8;
    case CameraModel::kFullOpenCV: return 12;
  }
  return 0;
}

namespace {

// A whole token as an int in [0, INT_MAX]; false for anything else.
bool parse_size(const std::string& token, int* value) {
  if (token.empty() || token[0] < '0' || token[0] > '9') return false;
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(token.c_str(), &end, 10);
  if (end != token.c_str() + token.size() || errno == ERANGE || v > std::numeric_limits<int>::max()) return false;
  *value = static_cast<int>(v);
  return true;
}

}  // namespace

Camera camera_from_text(const std::string& text, const std::string& where) {
  std::istringstream in(text);
  std::vector<std::string> tokens;
  for (std::string token; in >> token;) tokens.push_back(token);
  int id = 0;
  if (!tokens.empty() && parse_size(tokens[0], &id)) tokens.erase(tokens.begin());  // a CAMERA_ID
  LMB_CHECK(tokens.size() >= 3, where << ": expected \"MODEL WIDTH HEIGHT PARAMS...\" (COLMAP cameras.txt, e.g. "
                                         "\"PINHOLE 640 480 fx fy cx cy\"), got '"
                                      << text << "'");
  Camera camera;
  camera.model = camera_model_from_name(tokens[0], where);
  LMB_CHECK(parse_size(tokens[1], &camera.width) && parse_size(tokens[2], &camera.height),
            where << ": WIDTH and HEIGHT must be whole numbers of pixels, got '" << tokens[1] << "' and '" << tokens[2]
                  << "'");
  for (size_t i = 3; i < tokens.size(); ++i) {
    camera.params.push_back(parse_finite_number(tokens[i], where, "camera parameter " + std::to_string(i - 3)));
  }
  camera.check(where);
  return camera;
}

std::string camera_to_text(const Camera& camera) {
  std::ostringstream out;
  out << camera_model_name(camera.model) << ' ' << camera.width << ' ' << camera.height;
  for (double p : camera.params) out << ' ' << exact_number_text(p);
  return out.str();
}

namespace {

bool single_focal(CameraModel m) {
  return m == CameraModel::kSimplePinhole || m == CameraModel::kSimpleRadial || m == CameraModel::kRadial;
}

}  // namespace

void Camera::check(const std::string& where) const {
  const int expected = camera_model_num_params(model);
  LMB_CHECK(static_cast<int>(params.size()) == expected, where << ": camera model " << camera_model_name(model)
                                                               << " takes " << expected << " parameters, got "
                                                               << params.size());
  LMB_CHECK(width > 0 && height > 0, where << ": image size must be positive, got " << width << "x" << height);
  for (size_t i = 0; i < params.size(); ++i) {
    LMB_CHECK(std::isfinite(params[i]), where << ": camera parameter " << i << " is not finite");
  }
  LMB_CHECK(params[0] > 0 && (single_focal(model) || params[1] > 0), where << ": focal length must be positive");
}

double Camera::mean_focal_length() const { return single_focal(model) ? params[0] : 0.5 * (params[0] + params[1]); }

Eigen::Vector2d Camera::principal_point() const {
  return single_focal(model) ? Eigen::Vector2d(params[1], params[2]) : Eigen::Vector2d(params[2], params[3]);
}

bool Camera::has_distortion() const {
  switch (model) {
    case CameraModel::kSimplePinhole:
    case CameraModel::kPinhole: return false;
    default:
      for (int i = single_focal(model) ? 3 : 4; i < static_cast<int>(params.size()); ++i) {
        if (params[i] != 0.0) return true;
      }
      return false;
  }
}

Eigen::Vector2d Camera::distortion(const Eigen::Vector2d& n) const {
  const double u = n.x(), v = n.y();
  const double u2 = u * u, v2 = v * v, uv = u * v, r2 = u2 + v2;
  const std::vector<double>& p = params;
  switch (model) {
    case CameraModel::kSimplePinhole:
    case CameraModel::kPinhole: return Eigen::Vector2d::Zero();
    case CameraModel::kSimpleRadial: {
      const double radial = p[3] * r2;
      return Eigen::Vector2d(u * radial, v * radial);
    }
    case CameraModel::kRadial: {
      const double radial = p[3] * r2 + p[4] * r2 * r2;
      return Eigen::Vector2d(u * radial, v * radial);
    }
    case CameraModel::kOpenCV: {
      const double k1 = p[4], k2 = p[5], p1 = p[6], p2 = p[7];
      const double radial = k1 * r2 + k2 * r2 * r2;
      return Eigen::Vector2d(u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2),
                             v * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2));
    }
    case CameraModel::kFullOpenCV: {
      const double k1 = p[4], k2 = p[5], p1 = p[6], p2 = p[7];
      const double k3 = p[8], k4 = p[9], k5 = p[10], k6 = p[11];
      const double r4 = r2 * r2, r6 = r4 * r2;
      const double radial = (1.0 + k1 * r2 + k2 * r4 + k3 * r6) / (1.0 + k4 * r2 + k5 * r4 + k6 * r6);
      return Eigen::Vector2d(u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2) - u,
                             v * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2) - v);
    }
  }
  return Eigen::Vector2d::Zero();
}

Eigen::Vector2d Camera::img_from_cam(const Eigen::Vector2d& n) const {
  const Eigen::Vector2d d = n + distortion(n);
  if (single_focal(model)) {
    return Eigen::Vector2d(params[0] * d.x() + params[1], params[0] * d.y() + params[2]);
  }
  return Eigen::Vector2d(params[0] * d.x() + params[2], params[1] * d.y() + params[3]);
}

Eigen::Vector2d Camera::cam_from_img(const Eigen::Vector2d& pixel) const {
  Eigen::Vector2d d;
  if (single_focal(model)) {
    d = Eigen::Vector2d((pixel.x() - params[1]) / params[0], (pixel.y() - params[2]) / params[0]);
  } else {
    d = Eigen::Vector2d((pixel.x() - params[2]) / params[0], (pixel.y() - params[3]) / params[1]);
  }
  if (!has_distortion()) return d;
  // Newton's method on f(u) = u + distortion(u) - d with a central-difference Jacobian, as COLMAP's
  // IterativeUndistortion.
  constexpr int kMaxIterations = 100;
  constexpr double kMaxStepNorm = 1e-10;
  constexpr double kRelStepSize = 1e-6;
  Eigen::Vector2d u = d;
  for (int it = 0; it < kMaxIterations; ++it) {
    const double step0 = std::max(std::numeric_limits<double>::epsilon(), std::abs(kRelStepSize * u.x()));
    const double step1 = std::max(std::numeric_limits<double>::epsilon(), std::abs(kRelStepSize * u.y()));
    Eigen::Matrix2d J;
    const Eigen::Vector2d dx0 = distortion(u - Eigen::Vector2d(step0, 0));
    const Eigen::Vector2d dx1 = distortion(u + Eigen::Vector2d(step0, 0));
    const Eigen::Vector2d dy0 = distortion(u - Eigen::Vector2d(0, step1));
    const Eigen::Vector2d dy1 = distortion(u + Eigen::Vector2d(0, step1));
    J.col(0) = (dx1 - dx0) / (2 * step0);
    J.col(1) = (dy1 - dy0) / (2 * step1);
    J += Eigen::Matrix2d::Identity();
    const Eigen::Vector2d residual = u + distortion(u) - d;
    const Eigen::Vector2d step = J.inverse() * residual;
    u -= step;
    if (step.squaredNorm() < kMaxStepNorm) break;
  }
  return u;
}

bool Camera::project(const Eigen::Vector3d& x, Eigen::Vector2d* pixel) const {
  if (!(x.z() > 1e-9)) return false;
  *pixel = img_from_cam(Eigen::Vector2d(x.x() / x.z(), x.y() / x.z()));
  return true;
}

}  // namespace lmb
