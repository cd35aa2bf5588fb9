#include "infer/cv/feature_detection.h"

#include <algorithm>
#include <numeric>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace lmb {

namespace {

ImageFeatures detect_checked(const cv::Mat& image, const DetectorOptions& options) {
  // OpenCV's BRISK describes some keypoints differently in a view into a larger buffer (a
  // non-continuous Mat: an ROI, or rows with a stride) than in the same pixels stored alone, so a
  // view is copied first: the result depends on the pixels only, as the mapper's does.
  cv::Mat gray = image.isContinuous() ? image : image.clone();
  if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
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
            "detect_features: " << options.detector << " returned descriptors of unexpected shape");
  std::vector<int> order(keypoints.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return stronger(keypoints[a], keypoints[b]); });
  if (order.size() > static_cast<size_t>(options.max_keypoints)) order.resize(options.max_keypoints);
  out.keypoints.reserve(order.size());
  out.descriptors.reserve(order.size() * bytes);
  for (int i : order) {
    const cv::KeyPoint& kp = keypoints[i];
    // COLMAP's pixel convention (common/types.h): OpenCV's pt + 0.5.
    out.keypoints.push_back(Keypoint{kp.pt.x + 0.5f, kp.pt.y + 0.5f, kp.size, kp.angle});
    out.responses.push_back(kp.response);
    const uint8_t* row = descriptors.ptr<uint8_t>(i);
    out.descriptors.insert(out.descriptors.end(), row, row + bytes);
  }
  return out;
}

}  // namespace

ImageFeatures detect_features(const cv::Mat& image, const DetectorOptions& options) {
  options.check();
  LMB_CHECK(!image.empty() && image.depth() == CV_8U &&
                (image.channels() == 1 || image.channels() == 3 || image.channels() == 4),
            "detect_features: expected an 8-bit image with 1, 3 or 4 channels");
  options.check_image_size(image.cols, image.rows, "detect_features");
  try {
    return detect_checked(image, options);
  } catch (const cv::Exception& e) {
    // One line naming the image's size, not OpenCV's multi-line assertion text.
    LMB_FAIL("detect_features: OpenCV failed on a " << image.cols << "x" << image.rows << " image with "
                                                    << image.channels() << " channel(s): " << e.err << " (in " << e.func
                                                    << ")");
  }
}

}  // namespace lmb
