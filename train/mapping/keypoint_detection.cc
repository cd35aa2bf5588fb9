#include "train/mapping/keypoint_detection.h"

#include "common/error.h"

namespace lmb {

ImageFeatures detect_keypoints(const cv::Mat& gray, const DetectorOptions& options) {
  LMB_CHECK(!gray.empty() && gray.type() == CV_8UC1, "detect_keypoints: expected an 8-bit grayscale image");
  return detect_features(gray, options);
}

}  // namespace lmb
