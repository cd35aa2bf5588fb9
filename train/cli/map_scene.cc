#include "train/cli/map_scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <system_error>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/file_io.h"

namespace lmb::cli {

namespace fs = std::filesystem;

namespace {

// The image of a map frame in colour (BGR), or empty when it cannot be read. Checked first for a
// file that cannot be opened: OpenCV would print a warning of its own.
cv::Mat read_colour_image(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec) || !std::ifstream(path).good()) return cv::Mat();
  return cv::imread(path.string(), cv::IMREAD_COLOR);
}

// Per landmark, the mean colour of the pixels under its map-frame observations (COLMAP's pixel
// convention: pixel (col, row) covers [col, col + 1) x [row, row + 1)); grey where none was read.
std::vector<Eigen::Matrix<uint8_t, 3, 1>> landmark_colours(const LandmarkMap& map, const fs::path& images_dir,
                                                           SceneStats* stats) {
  std::vector<Eigen::Vector3d> sum(map.landmarks.size(), Eigen::Vector3d::Zero());
  std::vector<int32_t> count(map.landmarks.size(), 0);
  for (const MapFrame& frame : map.frames) {
    if (frame.is_query) continue;
    const cv::Mat image = images_dir.empty() ? cv::Mat() : read_colour_image(images_dir / frame.name);
    if (image.empty()) {
      ++stats->images_missing;
      continue;
    }
    ++stats->images_read;
    for (int32_t k = 0; k < frame.num_keypoints; ++k) {
      const int64_t kp = frame.first_keypoint + k;
      const landmark_t l = map.keypoint_landmark[kp];
      if (l == kInvalidLandmarkId) continue;
      const int col = std::clamp(static_cast<int>(std::floor(map.keypoints[kp].x)), 0, image.cols - 1);
      const int row = std::clamp(static_cast<int>(std::floor(map.keypoints[kp].y)), 0, image.rows - 1);
      const cv::Vec3b bgr = image.at<cv::Vec3b>(row, col);
      sum[l] += Eigen::Vector3d(bgr[2], bgr[1], bgr[0]);
      ++count[l];
    }
  }
  std::vector<Eigen::Matrix<uint8_t, 3, 1>> colours(map.landmarks.size(), kUnseenLandmarkColor);
  for (size_t l = 0; l < colours.size(); ++l) {
    if (count[l] == 0) continue;
    const Eigen::Vector3d mean = (sum[l] / count[l]).array().round().min(255.0).max(0.0);
    colours[l] = mean.cast<uint8_t>();
    ++stats->coloured_landmarks;
  }
  return colours;
}

// `name` with "-N" before its extension ("a.png" -> "a-2.png").
std::string numbered_name(const std::string& name, int n) {
  const fs::path p(name);
  const std::string stem = (p.parent_path() / p.stem()).string();
  return stem + "-" + std::to_string(n) + p.extension().string();
}

Rigid3d pose_of(const nlohmann::json& entry, const std::string& where) {
  LMB_CHECK(entry.contains("cam_from_world"), where << ": a localized entry without cam_from_world");
  const nlohmann::json& p = entry.at("cam_from_world");
  const Eigen::Quaterniond q = checked_rotation(p.at("qw").get<double>(), p.at("qx").get<double>(),
                                                p.at("qy").get<double>(), p.at("qz").get<double>(), where);
  const Eigen::Vector3d t(p.at("tx").get<double>(), p.at("ty").get<double>(), p.at("tz").get<double>());
  LMB_CHECK(t.allFinite(), where << ": cam_from_world translation is not finite");
  return Rigid3d(q, t);
}

}  // namespace

ColmapModel map_scene_model(const LandmarkMap& map, const std::vector<ScenePhoto>& photos, const fs::path& images_dir,
                            SceneStats* stats) {
  ColmapModel model;
  for (size_t c = 0; c < map.cameras.size(); ++c) model.cameras[static_cast<int>(c) + 1] = map.cameras[c];
  int image_id = 0;
  for (const MapFrame& frame : map.frames) {
    if (frame.is_query) continue;
    ColmapImage im;
    im.image_id = ++image_id;
    im.camera_id = static_cast<int>(frame.camera) + 1;
    im.name = frame.name;
    im.cam_from_world = frame.cam_from_world;
    im.points2d.resize(static_cast<size_t>(frame.num_keypoints));
    for (int32_t k = 0; k < frame.num_keypoints; ++k) {
      const int64_t kp = frame.first_keypoint + k;
      const Keypoint& keypoint = map.keypoints[kp];
      im.points2d[k].xy = Eigen::Vector2d(keypoint.x, keypoint.y);
      const landmark_t l = map.keypoint_landmark[kp];
      im.points2d[k].point3d_id = l == kInvalidLandmarkId ? ColmapPoint2D::kNoPoint3D : static_cast<int64_t>(l) + 1;
    }
    model.images.push_back(std::move(im));
  }
  // The photos' cameras: a camera of the map when it is the same, else one per distinct camera
  // after the map's.
  std::map<std::string, int> camera_ids;
  for (const auto& [id, camera] : model.cameras) camera_ids.emplace(camera_to_text(camera), id);
  for (const ScenePhoto& photo : photos) {
    check_image_name(photo.name, "scene: photo");
    const std::string key = camera_to_text(photo.camera);
    auto it = camera_ids.find(key);
    if (it == camera_ids.end()) {
      const int id = static_cast<int>(model.cameras.size()) + 1;
      model.cameras[id] = photo.camera;
      it = camera_ids.emplace(key, id).first;
    }
    ColmapImage im;
    im.image_id = ++image_id;
    im.camera_id = it->second;
    im.name = photo.name;
    im.cam_from_world = photo.cam_from_world;
    model.images.push_back(std::move(im));
  }
  const std::vector<Eigen::Matrix<uint8_t, 3, 1>> colours = landmark_colours(map, images_dir, stats);
  model.points.resize(map.landmarks.size());
  for (size_t l = 0; l < map.landmarks.size(); ++l) {
    model.points[l].point3d_id = static_cast<int64_t>(l) + 1;
    model.points[l].xyz = map.landmarks[l].position;
    model.points[l].rgb = colours[l];
    model.points[l].error = map.landmarks[l].mean_reprojection_error;
  }
  for (const ColmapImage& im : model.images) {
    for (size_t k = 0; k < im.points2d.size(); ++k) {
      const int64_t id = im.points2d[k].point3d_id;
      if (id != ColmapPoint2D::kNoPoint3D) model.points[id - 1].track.push_back({im.image_id, static_cast<int>(k)});
    }
  }
  return model;
}

std::vector<ScenePhoto> read_localized_poses(const fs::path& poses_json, const LandmarkMap& map) {
  const std::string where = poses_json.string();
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(read_file(poses_json));
  } catch (const nlohmann::json::exception& e) {
    LMB_FAIL(where << ": not a poses file of `lboost localize`: " << e.what());
  }
  const bool photos = j.contains("photos");
  LMB_CHECK(photos || j.contains("frames"),
            where << ": not a poses file of `lboost localize --image/--images/--map` (no \"photos\" or \"frames\")");
  std::vector<ScenePhoto> out;
  std::set<std::string> names;
  try {
    const Camera photo_camera =
        photos ? camera_from_text(j.at("camera").get<std::string>(), where + ": camera") : Camera();
    for (const nlohmann::json& entry : j.at(photos ? "photos" : "frames")) {
      if (!entry.value("success", false)) continue;
      ScenePhoto p;
      const std::string source = entry.at(photos ? "path" : "name").get<std::string>();
      p.name = "localized/" + (photos ? fs::path(source).filename().string() : source);
      for (int n = 2; !names.insert(p.name).second; ++n) p.name = numbered_name(p.name, n);
      p.cam_from_world = pose_of(entry, where + ": " + source);
      if (photos) {
        p.camera = photo_camera;
      } else {
        const auto frame =
            std::find_if(map.frames.begin(), map.frames.end(), [&](const MapFrame& f) { return f.name == source; });
        LMB_CHECK(frame != map.frames.end(), where << ": frame '" << source << "' is not in the map");
        p.camera = map.cameras[frame->camera];
      }
      out.push_back(std::move(p));
    }
  } catch (const nlohmann::json::exception& e) {
    LMB_FAIL(where << ": not a poses file of `lboost localize`: " << e.what());
  }
  return out;
}

void write_scene_ply(const ColmapModel& model, size_t num_map_images, const fs::path& path) {
  std::ostringstream out;
  out << "ply\nformat ascii 1.0\n"
      << "comment LandmarkBoost scene: " << model.points.size() << " landmarks, then " << num_map_images
      << " map frame centres (blue), then " << model.images.size() - num_map_images
      << " localized camera centres (red)\n"
      << "element vertex " << model.points.size() + model.images.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  char line[160];
  auto vertex = [&](const Eigen::Vector3d& x, const Eigen::Matrix<uint8_t, 3, 1>& rgb) {
    std::snprintf(line, sizeof(line), "%.9g %.9g %.9g %d %d %d\n", x.x(), x.y(), x.z(), rgb[0], rgb[1], rgb[2]);
    out << line;
  };
  for (const ColmapPoint3D& p : model.points) vertex(p.xyz, p.rgb);
  for (size_t i = 0; i < model.images.size(); ++i) {
    vertex(model.images[i].cam_from_world.center(), i < num_map_images ? kMapFrameColor : kLocalizedColor);
  }
  write_file_atomically(path, out.str());
}

}  // namespace lmb::cli
