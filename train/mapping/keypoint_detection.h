// Binary keypoint detection (BRISK or ORB through OpenCV) for the mapper.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/types.h"

namespace lmb {

struct DetectorOptions {
  std::string detector = "BRISK";  // "BRISK" (64-byte descriptors) or "ORB" (32 bytes)
  int max_keypoints = 1500;        // per image, the strongest by detector response
  int brisk_threshold = 30;        // BRISK FAST/AGAST threshold (intensity levels)
  int brisk_octaves = 3;
  void check() const;  // throws lmb::Error naming the field
};

// Descriptor size in bytes of a detector name; throws lmb::Error for unknown names.
int detector_descriptor_bytes(const std::string& detector);

// Keypoints of one image with their descriptors as flat rows of descriptor_bytes each.
struct ImageFeatures {
  std::vector<Keypoint> keypoints;
  std::vector<uint8_t> descriptors;  // keypoints.size() * descriptor_bytes
  std::vector<float> responses;      // detector response per keypoint (not stored in the map)
};

// Detects keypoints in an 8-bit grayscale image and computes their descriptors. Keypoints are
// sorted by decreasing response (ties by position) and capped at options.max_keypoints; x, y are
// COLMAP pixel coordinates (OpenCV's + 0.5), scale is KeyPoint::size, angle KeyPoint::angle.
// Deterministic for a given image.
ImageFeatures detect_keypoints(const cv::Mat& gray, const DetectorOptions& options);

}  // namespace lmb
