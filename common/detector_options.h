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

  // The smallest width and height (pixels) the detector takes: OpenCV fails with an assertion on
  // smaller images. BRISK's scale space has 2 * octaves layers, the last at a third of the image
  // per 2^(octaves - 2) (6 px at the default 3 octaves; layers under 3 px fail too); ORB's pyramid
  // needs 2 px.
  int min_image_side() const {
    if (detector == "ORB") return 2;
    if (brisk_octaves == 0) return 1;
    return brisk_octaves == 1 ? 3 : 3 << (brisk_octaves - 2);
  }

  // Throws lmb::Error "<what>: image is WxH pixels, smaller than the NxN that <detector> takes"
  // for an image the detector cannot take (see min_image_side).
  void check_image_size(int width, int height, const std::string& what) const {
    const int side = min_image_side();
    LMB_CHECK(width >= side && height >= side,
              what << ": image is " << width << "x" << height << " pixels, smaller than the " << side << "x" << side
                   << " that " << detector
                   << (detector == "BRISK" ? " with " + std::to_string(brisk_octaves) + " octaves" : std::string())
                   << " takes");
  }
};

}  // namespace lmb
