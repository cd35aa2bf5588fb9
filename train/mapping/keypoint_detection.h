// Binary keypoint detection (BRISK or ORB through OpenCV) for the mapper. The detection itself is
// the inference library's OpenCV front-end (infer/cv/feature_detection.h) and the settings are
// common/detector_options.h, so query frames of an app are detected exactly as the map.
#pragma once

#include <opencv2/core.hpp>

#include "common/detector_options.h"
#include "infer/cv/feature_detection.h"

namespace lmb {

// detect_features for an 8-bit grayscale image (what the mapper reads); throws lmb::Error for
// anything else or invalid options.
ImageFeatures detect_keypoints(const cv::Mat& gray, const DetectorOptions& options);

}  // namespace lmb
