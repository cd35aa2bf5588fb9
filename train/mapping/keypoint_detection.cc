#include "train/mapping/keypoint_detection.h"

#include <algorithm>
#include <numeric>

#include <opencv2/features2d.hpp>

#include "common/error.h"

namespace lmb {

void DetectorOptions::check() const {
  detector_descriptor_bytes(detector);
  LMB_CHECK(max_keypoints > 0, "detector options: max_keypoints must be positive, got " << max_keypoints);
  LMB_CHECK(brisk_threshold > 0 && brisk_threshold < 256,
            "detector options: brisk_threshold must be in 1..255, got " << brisk_threshold);
  LMB_CHECK(brisk_octaves >= 0 && brisk_octaves <= 8,
            "detector options: brisk_octaves must be in 0..8, got " << brisk_octaves);
}

int detector_descriptor_bytes(const std::string& detector) {
  if (detector == "BRISK") return 64;
  if (detector == "ORB") return 32;
  LMB_FAIL("detector: unknown detector '" << detector << "' (expected BRISK or ORB)");
}

ImageFeatures detect_keypoints(const cv::Mat& gray, const DetectorOptions& options) {
  options.check();
  LMB_CHECK(!gray.empty() && gray.type() == CV_8UC1, "detect_keypoints: expected an 8-bit grayscale image");
  cv::Ptr<cv::Feature2D> detector;
  if (options.detector == "BRISK") {
    detector = cv::BRISK::create(options.brisk_threshold, options.brisk_octaves);
  } else {
    // ORB keeps its own strongest-N; ask for a margin so the response sort below decides.
    detector = cv::ORB::create(options.max_keypoints * 2);
  }
  std::vector<cv::KeyPoint> keypoints;
  detector->detect(gray, keypoints);
  // Cap before describing (describing is the expensive part), with a margin for keypoints the
  // descriptor drops at the border.
  auto stronger = [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
    if (a.response != b.response) return a.response > b.response;
    if (a.pt.y != b.pt.y) return a.pt.y < b.pt.y;
    if (a.pt.x != b.pt.x) return a.pt.x < b.pt.x;
    return a.size < b.size;
  };
  std::sort(keypoints.begin(), keypoints.end(), stronger);
  const size_t margin = static_cast<size_t>(options.max_keypoints) * 5 / 4 + 16;
  if (keypoints.size() > margin) keypoints.resize(margin);
  cv::Mat descriptors;
  detector->compute(gray, keypoints, descriptors);

  const int bytes = detector_descriptor_bytes(options.detector);
  ImageFeatures out;
  if (keypoints.empty()) return out;
  LMB_CHECK(descriptors.cols == bytes && descriptors.type() == CV_8UC1 &&
                descriptors.rows == static_cast<int>(keypoints.size()),
            "detect_keypoints: " << options.detector << " returned descriptors of unexpected shape");
  std::vector<int> order(keypoints.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return stronger(keypoints[a], keypoints[b]); });
  if (order.size() > static_cast<size_t>(options.max_keypoints)) order.resize(options.max_keypoints);
  out.keypoints.reserve(order.size());
  out.descriptors.reserve(order.size() * bytes);
  for (int i : order) {
    const cv::KeyPoint& kp = keypoints[i];
    out.keypoints.push_back(Keypoint{kp.pt.x + 0.5f, kp.pt.y + 0.5f, kp.size, kp.angle});
    out.responses.push_back(kp.response);
    const uint8_t* row = descriptors.ptr<uint8_t>(i);
    out.descriptors.insert(out.descriptors.end(), row, row + bytes);
  }
  return out;
}

}  // namespace lmb
