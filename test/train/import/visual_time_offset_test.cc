#include "train/import/visual_time_offset.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "common/random.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

// A camera rotating about its centre (no parallax) with a changing rate: oscillations about y and x.
Eigen::Quaterniond world_from_cam(double t) {
  const double s = t - 10.0;
  return Eigen::Quaterniond(Eigen::AngleAxisd(0.15 * std::sin(2 * M_PI * 1.5 * s), Eigen::Vector3d::UnitY()) *
                            Eigen::AngleAxisd(0.08 * std::sin(2 * M_PI * 1.1 * s + 0.7), Eigen::Vector3d::UnitX()));
}

// Writes a 1.5 s sequence at 30 Hz of a random texture seen by a PINHOLE camera (f = 300,
// 320x240) and 100 Hz ground truth that lags the images by `gt_lag` seconds.
void write_rotating_sequence(const fs::path& dir, double gt_lag, const Camera& camera) {
  fs::create_directories(dir / "rgb");
  Rng rng(42);
  cv::Mat coarse(90, 120, CV_8UC1);
  for (int y = 0; y < coarse.rows; ++y) {
    for (int x = 0; x < coarse.cols; ++x) coarse.at<uint8_t>(y, x) = static_cast<uint8_t>(rng.below(256));
  }
  cv::Mat texture;
  cv::resize(coarse, texture, cv::Size(960, 720), 0, 0, cv::INTER_CUBIC);
  Eigen::Matrix3d k;
  // OpenCV's pixel centres are integers, COLMAP's (the camera's) half-integers.
  k << camera.params[0], 0, camera.params[2] - 0.5, 0, camera.params[1], camera.params[3] - 0.5, 0, 0, 1;
  Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();  // reference image -> texture pixels
  shift(0, 2) = 320;
  shift(1, 2) = 240;
  std::ofstream rgb(dir / "rgb.txt");
  for (int i = 0; i < 45; ++i) {
    const double t = 10.0 + i / 30.0;
    // Texture pixel of image pixel x, both with OpenCV's integer centres.
    const Eigen::Matrix3d h = shift * k * world_from_cam(t).toRotationMatrix() * k.inverse();
    cv::Mat hm(3, 3, CV_64F);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) hm.at<double>(r, c) = h(r, c);
    }
    cv::Mat image;
    cv::warpPerspective(texture, image, hm, cv::Size(camera.width, camera.height),
                        cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
    char name[64];
    std::snprintf(name, sizeof(name), "rgb/%.6f.png", t);
    ASSERT_TRUE(cv::imwrite((dir / name).string(), image));
    rgb << std::setprecision(17) << t << ' ' << name << '\n';
  }
  std::ofstream gt(dir / "groundtruth.txt");
  gt << std::setprecision(17);
  for (int k2 = 0; k2 <= 170; ++k2) {
    const double stamp = 9.9 + 0.01 * k2;
    const Eigen::Quaterniond q = world_from_cam(stamp - gt_lag);
    gt << stamp << " 0 0 0 " << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  }
}

TEST(VisualTimeOffset, FindsTheLagOfTheGroundTruth) {
  const fs::path dir = fs::temp_directory_path() / ("lmb_visual_offset_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const Camera camera = parse_camera_line("PINHOLE 320 240 300 300 160 120");
  for (double lag : {0.0, 0.02}) {
    write_rotating_sequence(dir, lag, camera);
    const TimeOffsetScan scan =
        scan_time_offset_visual(dir, read_tum_image_list(dir / "rgb.txt"), read_tum_trajectory(dir / "groundtruth.txt"),
                                camera, 0.04, 0.005, 0.02);
    EXPECT_GE(scan.pairs, 40) << "lag " << lag;
    EXPECT_NEAR(scan.best_offset_s, lag, 1e-9) << "lag " << lag;
    ASSERT_EQ(scan.offset_s.size(), 17u);
    // At the true offset the rotations agree to a small fraction of a degree.
    const size_t best = static_cast<size_t>(std::lround((lag + 0.04) / 0.005));
    EXPECT_LT(scan.median_deg[best], 0.05) << "lag " << lag;
    EXPECT_GT(scan.median_deg.front(), 2 * scan.median_deg[best]) << "lag " << lag;
  }
  fs::remove_all(dir);
}

TEST(VisualTimeOffset, FailsWithoutUsablePairs) {
  const fs::path dir = fs::temp_directory_path() / ("lmb_visual_offset_flat_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "rgb");
  std::vector<TumImage> images;
  for (int i = 0; i < 3; ++i) {
    TumImage im;
    im.time_s = i;
    im.file = "rgb/" + std::to_string(i) + ".png";
    ASSERT_TRUE(cv::imwrite((dir / im.file).string(), cv::Mat(60, 80, CV_8UC1, cv::Scalar(128))));
    images.push_back(im);
  }
  TumTrajectory trajectory;
  trajectory.time_s = {0, 1, 2};
  trajectory.world_from_cam.resize(3);
  EXPECT_THROW(scan_time_offset_visual(dir, images, trajectory, parse_camera_line("PINHOLE 80 60 50 50 40 30"), 0.01,
                                       0.005, 0.02),
               Error);
  fs::remove(dir / images[1].file);
  try {
    scan_time_offset_visual(dir, images, trajectory, parse_camera_line("PINHOLE 80 60 50 50 40 30"), 0.01, 0.005, 0.02);
    ADD_FAILURE() << "missing image accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("1.png: cannot read image"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lmb
