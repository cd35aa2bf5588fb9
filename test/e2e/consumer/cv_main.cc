// The optional OpenCV front-end from the installed package (LandmarkBoost::infer_cv): detect the
// keypoints of a synthetic image and check the pixel convention against OpenCV's own BRISK.
#include <cstdio>
#include <vector>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "infer/cv/feature_detection.h"

int main() {
  cv::Mat image(240, 320, CV_8UC3, cv::Scalar(40, 40, 40));
  for (int i = 0; i < 12; ++i) {
    cv::rectangle(image, cv::Rect(10 + 25 * i, 20 + 13 * (i % 5), 18, 30), cv::Scalar(220, 200, 210), cv::FILLED);
    cv::circle(image, cv::Point(20 + 24 * i, 180 - 9 * (i % 4)), 7, cv::Scalar(250, 250, 250), cv::FILLED);
  }
  const lmb::ImageFeatures f = lmb::detect_features(image);
  cv::Mat gray;
  cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  std::vector<cv::KeyPoint> raw;
  const lmb::DetectorOptions o;
  cv::BRISK::create(o.brisk_threshold, o.brisk_octaves)->detect(gray, raw);
  int found = 0;
  for (const lmb::Keypoint& k : f.keypoints) {
    for (const cv::KeyPoint& r : raw) {
      if (r.pt.x + 0.5f == k.x && r.pt.y + 0.5f == k.y) {
        ++found;
        break;
      }
    }
  }
  const bool ok = !f.keypoints.empty() && found == static_cast<int>(f.keypoints.size()) &&
                  f.descriptors.size() == f.keypoints.size() * 64;
  std::printf("%s: infer_cv detected %zu keypoints (%d at OpenCV's pt + 0.5)\n", ok ? "ok  " : "FAIL",
              f.keypoints.size(), found);
  return ok ? 0 : 1;
}
