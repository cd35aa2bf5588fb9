#include "train/import/visual_time_offset.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

namespace {

struct VisualPair {
  double t0 = 0, t1 = 0;
  Eigen::Matrix3d cam1_from_cam0 = Eigen::Matrix3d::Identity();
};

constexpr int kMinInliers = 30;
constexpr int kRansacIterations = 300;

// Least-squares rotation R with b ~ R * a over the given indices (Kabsch).
Eigen::Matrix3d fit_rotation(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                             const std::vector<int>& indices) {
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (int i : indices) h += a[i] * b[i].transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() > 0 ? 1.0 : -1.0;
  return svd.matrixV() * d * svd.matrixU().transpose();
}

std::vector<int> rotation_inliers(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                                  const Eigen::Matrix3d& r, double max_angle_rad) {
  std::vector<int> inliers;
  const double min_cos = std::cos(max_angle_rad);
  for (size_t i = 0; i < a.size(); ++i) {
    if ((r * a[i]).dot(b[i]) >= min_cos) inliers.push_back(static_cast<int>(i));
  }
  return inliers;
}

}  // namespace

TimeOffsetScan scan_time_offset_visual(const std::filesystem::path& data_dir, const std::vector<TumImage>& images,
                                       const TumTrajectory& trajectory, const Camera& camera, double max_offset_s,
                                       double step_s, double max_gap_s) {
  LMB_CHECK(step_s > 0 && max_offset_s >= 0, "time offset scan: step must be positive and range non-negative");
  cv::Ptr<cv::ORB> orb = cv::ORB::create(1500);
  cv::BFMatcher matcher(cv::NORM_HAMMING, /*crossCheck=*/true);
  const double threshold = 3.0 / camera.mean_focal_length();  // 3 pixels, as an angle (rad)
  std::vector<VisualPair> pairs;
  std::vector<cv::KeyPoint> previous_keypoints;
  cv::Mat previous_descriptors;
  for (size_t i = 0; i < images.size(); ++i) {
    const std::filesystem::path path = data_dir / images[i].file;
    const cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
    LMB_CHECK(!image.empty(), path.string() << ": cannot read image");
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat descriptors;
    orb->detectAndCompute(image, cv::noArray(), keypoints, descriptors);
    if (i > 0 && !previous_descriptors.empty() && !descriptors.empty()) {
      std::vector<cv::DMatch> matches;
      matcher.match(previous_descriptors, descriptors, matches);
      std::vector<Eigen::Vector3d> b0, b1;  // bearing vectors in frames i-1 and i
      for (const cv::DMatch& m : matches) {
        // OpenCV's pixel centres are integers; COLMAP's (and Camera's) are at +0.5.
        const cv::Point2f& a = previous_keypoints[m.queryIdx].pt;
        const cv::Point2f& b = keypoints[m.trainIdx].pt;
        b0.push_back(camera.cam_from_img(Eigen::Vector2d(a.x + 0.5, a.y + 0.5)).homogeneous().normalized());
        b1.push_back(camera.cam_from_img(Eigen::Vector2d(b.x + 0.5, b.y + 0.5)).homogeneous().normalized());
      }
      if (b0.size() >= static_cast<size_t>(kMinInliers)) {
        Rng rng(counter_hash(0x7153, i));
        std::vector<int> best_inliers;
        for (int it = 0; it < kRansacIterations; ++it) {
          const int x = static_cast<int>(rng.below(b0.size()));
          const int y = static_cast<int>(rng.below(b0.size()));
          if (x == y || b0[x].cross(b0[y]).norm() < 1e-3) continue;
          std::vector<int> inliers = rotation_inliers(b0, b1, fit_rotation(b0, b1, {x, y}), threshold);
          if (inliers.size() > best_inliers.size()) best_inliers = std::move(inliers);
        }
        if (best_inliers.size() >= static_cast<size_t>(kMinInliers)) {
          // Refine on the inliers, once more on the refined inliers.
          Eigen::Matrix3d r = fit_rotation(b0, b1, best_inliers);
          best_inliers = rotation_inliers(b0, b1, r, threshold);
          if (best_inliers.size() >= static_cast<size_t>(kMinInliers)) {
            VisualPair pair;
            pair.t0 = images[i - 1].time_s;
            pair.t1 = images[i].time_s;
            pair.cam1_from_cam0 = fit_rotation(b0, b1, best_inliers);
            pairs.push_back(pair);
          }
        }
      }
    }
    previous_keypoints = std::move(keypoints);
    previous_descriptors = descriptors;
  }
  LMB_CHECK(!pairs.empty(), data_dir.string() << ": no consecutive frame pair with " << kMinInliers
                                              << " matches for the time offset scan");

  TimeOffsetScan scan;
  scan.pairs = static_cast<int>(pairs.size());
  const int steps = static_cast<int>(std::floor(max_offset_s / step_s + 1e-9));
  double best = 1e300;
  for (int s = -steps; s <= steps; ++s) {
    const double offset = s * step_s;
    std::vector<double> errors;
    for (const VisualPair& p : pairs) {
      const std::optional<Rigid3d> a = interpolate_pose(trajectory, p.t0 + offset, max_gap_s);
      const std::optional<Rigid3d> b = interpolate_pose(trajectory, p.t1 + offset, max_gap_s);
      if (!a || !b) continue;
      const Eigen::Matrix3d truth = (b->rotation.conjugate() * a->rotation).toRotationMatrix();
      errors.push_back(Eigen::AngleAxisd(truth.transpose() * p.cam1_from_cam0).angle() * 180.0 / M_PI);
    }
    double median = 0;
    if (!errors.empty()) {
      std::nth_element(errors.begin(), errors.begin() + static_cast<long>(errors.size() / 2), errors.end());
      median = errors[errors.size() / 2];
      if (median < best) {
        best = median;
        scan.best_offset_s = offset;
      }
    }
    scan.offset_s.push_back(offset);
    scan.median_deg.push_back(median);
    scan.pairs_used.push_back(static_cast<int>(errors.size()));
  }
  return scan;
}

}  // namespace lmb
