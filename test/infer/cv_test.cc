// The OpenCV front-end (lmb_infer_cv): on a rendered image, the keypoints and descriptors an app
// gets from a colour image equal the mapper's detection of the grayscale file with the mapper's
// default settings, in COLMAP's pixel convention (OpenCV's pt + 0.5).
#include "infer/cv/feature_detection.h"

#include <unistd.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "train/mapping/mapper.h"
#include "train/world/renderer.h"
#include "train/world/trajectory.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

TEST(InferCvTest, ColourImageGivesTheMappersKeypointsAndDescriptors) {
  const World world = build_world(world_preset("tiny"));
  const RayTable rays(world_camera(), 1);
  const Session session = make_map_session(world, 3);
  const MapperOptions mapper;  // the mapper's default detector settings
  size_t total = 0;
  for (int f = 0; f < 3; ++f) {
    const RenderedFrame frame = render_frame(world, rays, session.cam_from_world[f], session.lighting, f, 2);
    const fs::path path = fs::temp_directory_path() / ("lmb_infer_cv_" + std::to_string(::getpid()) + ".png");
    ASSERT_TRUE(cv::imwrite(path.string(), frame.image));
    const cv::Mat gray = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);  // as the mapper reads
    const cv::Mat colour = cv::imread(path.string(), cv::IMREAD_COLOR);    // as an app might
    fs::remove(path);
    ASSERT_EQ(colour.channels(), 3);

    const ImageFeatures expected = detect_keypoints(gray, mapper.detector);
    const ImageFeatures got = detect_features(colour);
    ASSERT_EQ(got.keypoints.size(), expected.keypoints.size()) << "frame " << f;
    ASSERT_EQ(got.descriptors, expected.descriptors) << "frame " << f;
    for (size_t i = 0; i < got.keypoints.size(); ++i) {
      EXPECT_EQ(got.keypoints[i].x, expected.keypoints[i].x) << i;
      EXPECT_EQ(got.keypoints[i].y, expected.keypoints[i].y) << i;
      EXPECT_EQ(got.keypoints[i].scale, expected.keypoints[i].scale) << i;
      EXPECT_EQ(got.keypoints[i].angle, expected.keypoints[i].angle) << i;
    }
    EXPECT_EQ(got.descriptors.size(), got.keypoints.size() * 64);
    total += got.keypoints.size();
    // The same pixels as a view into a wider image (an ROI, rows with a stride): the same result.
    cv::Mat wide(gray.rows + 8, gray.cols + 24, CV_8UC1, cv::Scalar(77));
    const cv::Mat roi = wide(cv::Rect(0, 0, gray.cols, gray.rows));
    gray.copyTo(roi);
    ASSERT_FALSE(roi.isContinuous());
    const ImageFeatures from_roi = detect_features(roi);
    ASSERT_EQ(from_roi.descriptors, expected.descriptors) << "frame " << f;

    // Pixel convention: every keypoint is one of OpenCV's BRISK keypoints moved by +0.5.
    std::vector<cv::KeyPoint> raw;
    cv::BRISK::create(mapper.detector.brisk_threshold, mapper.detector.brisk_octaves)->detect(gray, raw);
    int found = 0;
    for (const Keypoint& k : got.keypoints) {
      for (const cv::KeyPoint& r : raw) {
        if (r.pt.x + 0.5f == k.x && r.pt.y + 0.5f == k.y && r.size == k.scale) {
          ++found;
          break;
        }
      }
    }
    EXPECT_EQ(found, static_cast<int>(got.keypoints.size())) << "frame " << f;
  }
  EXPECT_GT(total, 100u);
}

TEST(InferCvTest, RejectsBadImagesAndOptions) {
  EXPECT_THROW(detect_features(cv::Mat()), Error);
  EXPECT_THROW(detect_features(cv::Mat(40, 40, CV_32FC1, cv::Scalar(0))), Error);
  EXPECT_THROW(detect_features(cv::Mat(40, 40, CV_8UC2, cv::Scalar(0))), Error);
  DetectorOptions o;
  o.detector = "SIFT";
  EXPECT_THROW(detect_features(cv::Mat(40, 40, CV_8UC1, cv::Scalar(0)), o), Error);
  EXPECT_TRUE(detect_features(cv::Mat(40, 40, CV_8UC1, cv::Scalar(0))).keypoints.empty());
}

// OpenCV's pyramids fail with a multi-line assertion on tiny images: checked first, one line with the
// image's size and the detector's minimum.
TEST(InferCvTest, ImagesSmallerThanTheDetectorTakesAreOneLineErrors) {
  cv::Mat noise(200, 200, CV_8UC1);
  cv::randu(noise, 0, 255);
  auto error = [&](int width, int height, const DetectorOptions& o) -> std::string {
    try {
      detect_features(noise(cv::Rect(0, 0, width, height)), o);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  const DetectorOptions brisk;
  EXPECT_EQ(brisk.min_image_side(), 6);
  EXPECT_EQ(error(5, 40, brisk),
            "detect_features: image is 5x40 pixels, smaller than the 6x6 that BRISK with 3 "
            "octaves takes");
  EXPECT_EQ(error(1, 1, brisk),
            "detect_features: image is 1x1 pixels, smaller than the 6x6 that BRISK with 3 "
            "octaves takes");
  try {
    detect_features(cv::Mat(5, 40, CV_8UC3, cv::Scalar(10, 200, 30)));
    ADD_FAILURE() << "a 40x5 colour image was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("image is 40x5 pixels"), std::string::npos) << e.what();
  }
  EXPECT_EQ(error(6, 6, brisk), "");
  DetectorOptions orb;
  orb.detector = "ORB";
  EXPECT_EQ(error(1, 9, orb), "detect_features: image is 1x9 pixels, smaller than the 2x2 that ORB takes");
  EXPECT_EQ(error(2, 2, orb), "");
  // Every size from the minimum up works, at every octave count.
  for (int octaves = 0; octaves <= 8; ++octaves) {
    DetectorOptions o;
    o.brisk_octaves = octaves;
    const int side = o.min_image_side();
    SCOPED_TRACE(octaves);
    if (side > 1) {
      EXPECT_NE(error(side - 1, 200, o), "");
      EXPECT_NE(error(200, side - 1, o), "");
    }
    for (int w = side; w < side + 8; ++w) EXPECT_EQ(error(w, side + (w % 3), o), "");
  }
}

}  // namespace
}  // namespace lmb
