#include "train/mapping/keypoint_detection.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "common/hamming.h"
#include "common/random.h"

namespace lmb {
namespace {

cv::Mat textured_image(int width, int height, uint64_t seed) {
  Rng rng(seed);
  cv::Mat img(height, width, CV_8UC1, cv::Scalar(90));
  for (int i = 0; i < 160; ++i) {
    const cv::Point a(static_cast<int>(rng.below(width)), static_cast<int>(rng.below(height)));
    const cv::Point b = a + cv::Point(static_cast<int>(rng.below(40)) + 5, static_cast<int>(rng.below(40)) + 5);
    const cv::Scalar color(static_cast<double>(rng.below(256)));
    if (i % 2) {
      cv::rectangle(img, a, b, color, cv::FILLED);
    } else {
      cv::circle(img, a, static_cast<int>(rng.below(15)) + 3, color, cv::FILLED);
    }
  }
  // Pixel noise: flat regions would make BRISK's intensity comparisons ties that rounding decides.
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const int v = img.at<uint8_t>(y, x) + static_cast<int>(rng.below(21)) - 10;
      img.at<uint8_t>(y, x) = static_cast<uint8_t>(std::clamp(v, 0, 255));
    }
  }
  return img;
}

TEST(DetectKeypoints, CappedSortedAndDeterministic) {
  const cv::Mat img = textured_image(640, 480, 1);
  DetectorOptions options;
  options.max_keypoints = 300;
  const ImageFeatures a = detect_keypoints(img, options);
  const ImageFeatures b = detect_keypoints(img.clone(), options);
  ASSERT_EQ(a.keypoints.size(), 300u);
  EXPECT_EQ(a.descriptors.size(), 300u * 64);
  EXPECT_EQ(a.descriptors, b.descriptors);
  for (size_t i = 0; i < a.keypoints.size(); ++i) {
    EXPECT_EQ(a.keypoints[i].x, b.keypoints[i].x);
    EXPECT_GT(a.keypoints[i].scale, 0.f);
    EXPECT_GE(a.keypoints[i].angle, 0.f);  // BRISK assigns an orientation
    EXPECT_GE(a.keypoints[i].x, 0.5f);
    EXPECT_LE(a.keypoints[i].x, 640.f);
    if (i > 0) {
      EXPECT_GE(a.responses[i - 1], a.responses[i]);
    }
  }
}

TEST(DetectKeypoints, TranslationMovesKeypointsExactly) {
  // On the full-resolution layer (no octaves), an integer shift moves keypoints by exactly that
  // shift and leaves their descriptors unchanged: the pixel convention (+0.5) is applied uniformly.
  const cv::Mat img = textured_image(400, 300, 2);
  cv::Mat shifted(300 + 48, 400 + 24, CV_8UC1, cv::Scalar(90));
  img.copyTo(shifted(cv::Rect(24, 48, 400, 300)));
  DetectorOptions options;
  options.max_keypoints = 100000;
  options.brisk_octaves = 0;
  const ImageFeatures a = detect_keypoints(img, options);
  const ImageFeatures b = detect_keypoints(shifted, options);
  int interior = 0, found = 0, same_descriptor = 0;
  for (size_t i = 0; i < a.keypoints.size(); ++i) {
    const Keypoint& k = a.keypoints[i];
    if (k.x < 60 || k.y < 60 || k.x > 340 || k.y > 240) continue;
    ++interior;
    for (size_t j = 0; j < b.keypoints.size(); ++j) {
      const Keypoint& m = b.keypoints[j];
      if (std::abs(m.x - (k.x + 24)) < 1e-3 && std::abs(m.y - (k.y + 48)) < 1e-3 && m.scale == k.scale) {
        ++found;
        // BRISK samples its pattern at float positions: allow a bit or two of rounding difference.
        same_descriptor += hamming_distance(a.descriptors.data() + i * 64, b.descriptors.data() + j * 64, 64) <= 2;
        break;
      }
    }
  }
  ASSERT_GT(interior, 50);
  EXPECT_GE(found, 0.95 * interior);
  EXPECT_GE(same_descriptor, 0.95 * found);
}

TEST(DetectKeypoints, OrbAndEdgeCases) {
  const cv::Mat img = textured_image(320, 240, 3);
  DetectorOptions options;
  options.detector = "ORB";
  options.max_keypoints = 200;
  const ImageFeatures orb = detect_keypoints(img, options);
  EXPECT_GT(orb.keypoints.size(), 50u);
  EXPECT_LE(orb.keypoints.size(), 200u);
  EXPECT_EQ(orb.descriptors.size(), orb.keypoints.size() * 32);
  EXPECT_EQ(detector_descriptor_bytes("BRISK"), 64);

  const cv::Mat flat(240, 320, CV_8UC1, cv::Scalar(0));
  EXPECT_TRUE(detect_keypoints(flat, DetectorOptions{}).keypoints.empty());

  options.detector = "SIFT";
  EXPECT_THROW(detect_keypoints(img, options), Error);
  EXPECT_THROW(detect_keypoints(cv::Mat(), DetectorOptions{}), Error);
}

}  // namespace
}  // namespace lmb
