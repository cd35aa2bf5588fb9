// Per-pixel ray casting of a World through a real (distorted) camera: supersampled, mip-mapped
// texture lookups, ceiling-lamp shading and deterministic sensor noise. Output: an 8-bit grayscale
// image and a 16-bit z-depth map in millimetres (0 = no surface), both width x height.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "common/camera.h"
#include "common/rigid3.h"
#include "train/world/world_model.h"

namespace lmb {

// Per-pixel camera rays, computed once per camera: for every pixel the normalized undistorted
// coordinates (x/z, y/z) of its centre and of its supersampling x supersampling sub-samples.
class RayTable {
 public:
  // Throws lmb::Error when the camera is invalid or its undistortion does not round-trip to
  // 1e-3 px somewhere in the image (a lens model that folds over inside the image).
  RayTable(const Camera& camera, int supersampling);

  const Camera& camera() const { return camera_; }
  int supersampling() const { return ss_; }
  // Normalized coordinates of the centre of pixel (col, row).
  Eigen::Vector2f centre(int col, int row) const { return centres_[static_cast<size_t>(row) * camera_.width + col]; }
  // Normalized coordinates of sub-sample s in [0, supersampling^2) of pixel (col, row).
  Eigen::Vector2f sample(int col, int row, int s) const {
    return samples_[(static_cast<size_t>(row) * camera_.width + col) * ss_ * ss_ + s];
  }
  // Spacing of neighbouring pixel centres on the normalized plane around pixel (col, row).
  float spacing(int col, int row) const { return spacing_[static_cast<size_t>(row) * camera_.width + col]; }

 private:
  Camera camera_;
  int ss_ = 1;
  std::vector<Eigen::Vector2f> centres_, samples_;
  std::vector<float> spacing_;
};

// Lighting and exposure of a session.
struct Lighting {
  double ambient = 0.45;           // irradiance everywhere
  double lamp_power = 1.0;         // irradiance of a lamp at distance 0 (cosine-weighted)
  double lamp_range_m = 2.0;       // falloff 1 / (1 + (r / range)^2), cut off smoothly at 6 m
  std::vector<double> lamp_scale;  // per lamp of the world (empty: all 1; 0 = lamp off)
  double emissive = 1.5;           // radiance of lit lamp panels per unit albedo
  double gain = 1.0;               // grey = 255 * gain * radiance^exponent
  double exponent = 1.0;
  double noise_sigma = 1.5;  // Gaussian sensor noise in grey levels
  uint64_t noise_seed = 0;
  bool flat = false;  // tests: radiance = albedo, no lamps, no noise
};

struct RenderedFrame {
  cv::Mat image;     // CV_8UC1
  cv::Mat depth_mm;  // CV_16UC1, z-depth of the pixel centre's ray in mm, 0 = none
};

// Renders one frame with `threads` threads (rows interleaved). Deterministic: the result depends
// only on the arguments (frame_key seeds the noise), never on the thread count.
RenderedFrame render_frame(const World& world, const RayTable& rays, const Rigid3d& cam_from_world,
                           const Lighting& lighting, uint64_t frame_key, int threads);

// The first surface along origin + t * direction (t > 0): t, point and outward normal (facing the
// ray's origin side). `box` is the hit box's index or -1 for the corridor's surfaces, then
// `surface` says which. Returns false when nothing is hit (the origin is outside the corridor).
struct SurfaceHit {
  double t = 0.0;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  int box = -1;
  Surface surface = Surface::kFloor;
  int axis = 0;  // axis of the normal (0 = x, 1 = y, 2 = z)
};
bool cast_ray(const World& world, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, SurfaceHit* hit);

// Albedo in [0, 1] of a hit point; `footprint_m` is the sample's width on the surface seen head-on
// (for mip-level selection). Sets *emissive when the point is on a lamp panel.
float surface_albedo(const World& world, const SurfaceHit& hit, const Eigen::Vector3d& direction, double footprint_m,
                     bool* emissive);

}  // namespace lmb
