// The inference library's optional OpenCV front-end (library lmb_infer_cv, CMake target
// LandmarkBoost::infer_cv): an image -> keypoints and binary descriptors ready for
// lmb::Localizer, detected exactly as the mapper detects map images (the mapper calls this code,
// with the same DetectorOptions, common/detector_options.h).
//
//   const cv::Mat image = cv::imread("frame.png");          // BGR, BGRA or grayscale, 8 bit
//   lmb::ImageFeatures f = lmb::detect_features(image);     // BRISK, the mapper's defaults
//   lmb::LocalizeResult r = localizer.localize(camera, f.keypoints, f.descriptors.data(), gravity);
//
// Keypoints: lmb::Keypoint in COLMAP's pixel convention (OpenCV KeyPoint::pt + 0.5), scale =
// KeyPoint::size (detector diameter, pixels), angle = KeyPoint::angle; sorted by decreasing
// response (ties by position), at most options.max_keypoints. Deterministic for a given image,
// and the same for a view into a larger image (an ROI) as for its pixels alone.
// Colour images are converted with cv::cvtColor(..., COLOR_BGR2GRAY) (COLOR_BGRA2GRAY): pass the
// grayscale image itself when the map was built from images read as grayscale files, to get
// the mapper's pixels exactly.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "common/detector_options.h"
#include "common/types.h"
#include "infer/export.h"

namespace lmb {

// Keypoints of one image with their descriptors as flat rows of descriptor_bytes each.
struct ImageFeatures {
  std::vector<Keypoint> keypoints;
  std::vector<uint8_t> descriptors;  // keypoints.size() * descriptor_bytes
  std::vector<float> responses;      // detector response per keypoint
};

// Detects keypoints in an 8-bit image (1, 3 or 4 channels) and computes their descriptors.
// Throws lmb::Error for an empty image, another pixel type, an image smaller than the detector
// takes (DetectorOptions::min_image_side: 6x6 for BRISK's defaults), invalid options, or any other
// OpenCV failure (one line naming the image's size).
LMB_INFER_EXPORT ImageFeatures detect_features(const cv::Mat& image, const DetectorOptions& options = {});

}  // namespace lmb
