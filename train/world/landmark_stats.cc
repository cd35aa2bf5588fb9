#include "train/world/landmark_stats.h"

#include <chrono>
#include <cmath>
#include <unordered_map>
#include <vector>

#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/io/colmap_model.h"
#include "common/io/session_file.h"

namespace fs = std::filesystem;

namespace lmb {

namespace {

int64_t cell_coord(double v, double cell) { return static_cast<int64_t>(std::floor(v / cell)); }

uint64_t cell_key(int64_t x, int64_t y, int64_t z) {
  const auto q = [](int64_t v) { return static_cast<uint64_t>(v + (1 << 20)) & 0x1FFFFF; };
  return q(x) << 42 | q(y) << 21 | q(z);
}

// Greedy radius clustering of back-projected keypoints: a point joins the nearest cluster whose
// seed point lies within `radius`, else seeds a new cluster. Deterministic for a fixed order.
class PointClusters {
 public:
  explicit PointClusters(double radius) : radius_(radius) {}

  // Returns the cluster id of x, creating one when none is near.
  int find_or_add(const Eigen::Vector3d& x, bool create) {
    const int64_t cx = cell_coord(x.x(), radius_), cy = cell_coord(x.y(), radius_), cz = cell_coord(x.z(), radius_);
    int best = -1;
    double best_d2 = radius_ * radius_;
    for (int64_t dx = -1; dx <= 1; ++dx) {
      for (int64_t dy = -1; dy <= 1; ++dy) {
        for (int64_t dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find(cell_key(cx + dx, cy + dy, cz + dz));
          if (it == cells_.end()) continue;
          for (int id : it->second) {
            const double d2 = (seeds_[id] - x).squaredNorm();
            if (d2 < best_d2) {
              best_d2 = d2;
              best = id;
            }
          }
        }
      }
    }
    if (best >= 0 || !create) return best;
    seeds_.push_back(x);
    cells_[cell_key(cx, cy, cz)].push_back(static_cast<int>(seeds_.size()) - 1);
    return static_cast<int>(seeds_.size()) - 1;
  }
  size_t size() const { return seeds_.size(); }

 private:
  double radius_;
  std::vector<Eigen::Vector3d> seeds_;
  std::unordered_map<uint64_t, std::vector<int>> cells_;
};

}  // namespace

LandmarkStats estimate_landmarks(const fs::path& world_dir, double voxel_m) {
  const auto t0 = std::chrono::steady_clock::now();
  const ColmapModel model = read_colmap_text(world_dir / "sparse");
  // Map frames: those of map sessions (sessions.txt), or, in a collection without it, "map/...".
  std::vector<bool> image_is_map;
  if (fs::exists(world_dir / kSessionFileName)) {
    const std::vector<MapSession> sessions = read_session_file(world_dir / kSessionFileName);
    for (int32_t s : image_sessions(sessions, model, world_dir / kSessionFileName)) {
      image_is_map.push_back(sessions[static_cast<size_t>(s)].kind == SessionKind::kMap);
    }
  } else {
    for (const ColmapImage& im : model.images) image_is_map.push_back(im.name.rfind("map/", 0) == 0);
  }
  LandmarkStats stats;
  LMB_CHECK(voxel_m > 0.0, "landmark estimate: merge radius must be positive");
  PointClusters clusters(voxel_m);
  std::vector<int> last_frame, frames;  // per cluster
  std::vector<Eigen::Vector3d> query_points;
  auto brisk = cv::BRISK::create();
  for (size_t i = 0; i < model.images.size(); ++i) {
    const ColmapImage& im = model.images[i];
    const bool is_map = image_is_map[i];
    const Camera& cam = model.cameras.at(im.camera_id);
    const fs::path image_path = world_dir / "images" / im.name, depth_path = world_dir / "depth" / im.name;
    const cv::Mat image = cv::imread(image_path.string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat depth = cv::imread(depth_path.string(), cv::IMREAD_UNCHANGED);
    LMB_CHECK(!image.empty(), image_path.string() << ": missing or unreadable image");
    LMB_CHECK(!depth.empty() && depth.type() == CV_16UC1, depth_path.string() << ": missing or not a 16-bit depth map");
    std::vector<cv::KeyPoint> keypoints;
    brisk->detect(image, keypoints);
    const Rigid3d world_from_cam = im.cam_from_world.inverse();
    for (const cv::KeyPoint& kp : keypoints) {
      const int c = std::clamp(static_cast<int>(std::lround(kp.pt.x)), 0, depth.cols - 1);
      const int r = std::clamp(static_cast<int>(std::lround(kp.pt.y)), 0, depth.rows - 1);
      const uint16_t mm = depth.at<uint16_t>(r, c);
      if (mm == 0) continue;
      const Eigen::Vector2d n = cam.cam_from_img(Eigen::Vector2d(kp.pt.x + 0.5, kp.pt.y + 0.5));
      const Eigen::Vector3d x = world_from_cam * (mm * 1e-3 * Eigen::Vector3d(n.x(), n.y(), 1.0));
      if (is_map) {
        ++stats.map_keypoints;
        const int id = clusters.find_or_add(x, true);
        if (id >= static_cast<int>(frames.size())) {
          frames.push_back(0);
          last_frame.push_back(-1);
        }
        if (last_frame[id] != static_cast<int>(i)) {
          last_frame[id] = static_cast<int>(i);
          ++frames[id];
        }
      } else {
        query_points.push_back(x);
      }
    }
    ++(is_map ? stats.map_frames : stats.query_frames);
  }
  stats.points = static_cast<int64_t>(clusters.size());
  for (int f : frames) {
    stats.landmarks_3 += f >= 3;
    stats.landmarks_10 += f >= 10;
  }
  stats.query_keypoints = static_cast<int64_t>(query_points.size());
  for (const Eigen::Vector3d& x : query_points) {
    const int id = clusters.find_or_add(x, false);
    stats.query_on_landmark += id >= 0 && frames[id] >= 3;
  }
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return stats;
}

}  // namespace lmb
