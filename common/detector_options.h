// Binary keypoint detector settings, shared by the mapper (train/mapping) and the inference
// library's OpenCV front-end (infer/cv), so that query frames are detected exactly as the map was.
// Plain data without OpenCV: the detection itself is infer/cv/feature_detection.h.
#pragma once

#include <string>

#include "common/error.h"

namespace lmb {

// Descriptor size in bytes of a detector name; throws lmb::Error for unknown names.
inline int detector_descriptor_bytes(const std::string& detector) {
  if (detector == "BRISK") return 64;
  if (detector == "ORB") return 32;
  LMB_FAIL("detector: unknown detector '" << detector << "' (expected BRISK or ORB)");
}

struct DetectorOptions {
  std::string detector = "BRISK";  // "BRISK" (64-byte descriptors) or "ORB" (32 bytes)
  int max_keypoints = 1500;        // per image, the strongest by detector response
  int brisk_threshold = 30;        // BRISK FAST/AGAST threshold (intensity levels)
  int brisk_octaves = 3;

  // Throws lmb::Error naming the field.
  void check() const {
    detector_descriptor_bytes(detector);
    LMB_CHECK(max_keypoints > 0, "detector options: max_keypoints must be positive, got " << max_keypoints);
    LMB_CHECK(brisk_threshold > 0 && brisk_threshold < 256,
              "detector options: brisk_threshold must be in 1..255, got " << brisk_threshold);
    LMB_CHECK(brisk_octaves >= 0 && brisk_octaves <= 8,
              "detector options: brisk_octaves must be in 0..8, got " << brisk_octaves);
  }
};

}  // namespace lmb
