// Basic ids and small value types shared by every layer.
#pragma once

#include <cstdint>
#include <limits>

namespace lmb {

using landmark_t = int64_t;  // index into the map's landmarks
using frame_t = int32_t;     // index into the map's frames
using camera_t = int32_t;    // index into the map's cameras

constexpr landmark_t kInvalidLandmarkId = -1;  // keypoint without a landmark: background
constexpr frame_t kInvalidFrameId = -1;

// A detected keypoint in pixel coordinates of the distorted image, in COLMAP's convention: the
// centre of the top-left pixel is (0.5, 0.5), so an OpenCV KeyPoint::pt maps to pt + 0.5.
// scale: the detector's keypoint diameter in pixels (OpenCV KeyPoint::size).
// angle: the detector's orientation in degrees, or -1 when it has none.
struct Keypoint {
  float x = 0.f;
  float y = 0.f;
  float scale = 0.f;
  float angle = -1.f;
};

}  // namespace lmb
