#include "train/mapping/depth_ground_truth.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"

namespace lmb {

namespace fs = std::filesystem;

std::vector<Eigen::Vector3d> back_project_keypoints(const LandmarkMap& map, frame_t frame, const uint16_t* depth_mm,
                                                    int width, int height) {
  const MapFrame& f = map.frames.at(frame);
  const Camera& camera = map.cameras.at(f.camera);
  const Rigid3d world_from_cam = f.cam_from_world.inverse();
  std::vector<Eigen::Vector3d> points(f.num_keypoints, Eigen::Vector3d::Constant(std::nan("")));
  for (int i = 0; i < f.num_keypoints; ++i) {
    const Keypoint& k = map.keypoints[f.first_keypoint + i];
    const int col = static_cast<int>(std::floor(k.x));
    const int row = static_cast<int>(std::floor(k.y));
    if (col < 0 || row < 0 || col >= width || row >= height) continue;
    const uint16_t d = depth_mm[static_cast<size_t>(row) * width + col];
    if (d == 0) continue;
    const Eigen::Vector2d n = camera.cam_from_img(Eigen::Vector2d(k.x, k.y));
    points[i] = world_from_cam * (Eigen::Vector3d(n.x(), n.y(), 1.0) * (d * 1e-3));
  }
  return points;
}

MapAccuracy check_map_against_depth(const LandmarkMap& map, const fs::path& collection_dir,
                                    const DepthCheckOptions& options) {
  // Back-projected point per keypoint (NaN without depth or without landmark).
  std::vector<Eigen::Vector3d> point(map.keypoints.size(), Eigen::Vector3d::Constant(std::nan("")));
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const MapFrame& frame = map.frames[f];
    const fs::path path = collection_dir / "depth" / frame.name;
    const cv::Mat depth = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
    LMB_CHECK(!depth.empty(), path.string() << ": cannot read depth image");
    const Camera& camera = map.cameras[frame.camera];
    LMB_CHECK(depth.type() == CV_16UC1 && depth.cols == camera.width && depth.rows == camera.height,
              path.string() << ": expected a 16-bit " << camera.width << "x" << camera.height << " depth image");
    const cv::Mat continuous = depth.isContinuous() ? depth : depth.clone();
    const auto points = back_project_keypoints(map, f, continuous.ptr<uint16_t>(0), depth.cols, depth.rows);
    for (int i = 0; i < frame.num_keypoints; ++i) point[frame.first_keypoint + i] = points[i];
  }
  std::vector<std::vector<int64_t>> observations(map.landmarks.size());
  for (size_t k = 0; k < map.keypoint_landmark.size(); ++k) {
    if (map.keypoint_landmark[k] >= 0) observations[map.keypoint_landmark[k]].push_back(static_cast<int64_t>(k));
  }
  MapAccuracy a;
  std::vector<double> errors;
  double purity_sum = 0;
  int64_t agreeing = 0, pure_tracks = 0;
  const double r2 = options.purity_radius_m * options.purity_radius_m;
  for (size_t l = 0; l < observations.size(); ++l) {
    std::vector<Eigen::Vector3d> pts;
    for (int64_t k : observations[l]) {
      if (point[k].allFinite()) {
        pts.push_back(point[k]);
      } else {
        ++a.observations_without_depth;
      }
    }
    if (pts.size() < 2) continue;
    size_t best = 0;
    int best_count = -1;
    for (size_t i = 0; i < pts.size(); ++i) {
      int count = 0;
      for (const auto& q : pts) count += (q - pts[i]).squaredNorm() <= r2 ? 1 : 0;
      if (count > best_count) {
        best_count = count;
        best = i;
      }
    }
    Eigen::Vector3d majority = Eigen::Vector3d::Zero();
    for (const auto& q : pts) {
      if ((q - pts[best]).squaredNorm() <= r2) majority += q;
    }
    majority /= best_count;
    int agree = 0;
    for (const auto& q : pts) agree += (q - majority).squaredNorm() <= r2 ? 1 : 0;
    ++a.landmarks_checked;
    a.observations_checked += static_cast<int64_t>(pts.size());
    agreeing += agree;
    pure_tracks += agree == static_cast<int>(pts.size()) ? 1 : 0;
    purity_sum += static_cast<double>(agree) / static_cast<double>(pts.size());
    errors.push_back((map.landmarks[l].position - majority).norm());
  }
  if (a.landmarks_checked > 0) {
    a.mean_track_purity = purity_sum / static_cast<double>(a.landmarks_checked);
    a.observation_purity = static_cast<double>(agreeing) / static_cast<double>(a.observations_checked);
    a.pure_track_share = static_cast<double>(pure_tracks) / static_cast<double>(a.landmarks_checked);
    std::sort(errors.begin(), errors.end());
    a.median_position_error_m = errors[errors.size() / 2];
    a.p90_position_error_m = errors[errors.size() * 9 / 10];
    double sum = 0;
    for (double e : errors) sum += e;
    a.mean_position_error_m = sum / static_cast<double>(errors.size());
  }
  return a;
}

}  // namespace lmb
