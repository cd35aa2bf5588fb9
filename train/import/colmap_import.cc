#include "train/import/colmap_import.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>

#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/io/colmap_model.h"
#include "common/io/gravity_file.h"
#include "train/import/collection_writer.h"
#include "train/import/split_rule.h"
#include "train/import/tum_import.h"

namespace lmb {

namespace fs = std::filesystem;

void ColmapImportOptions::check() const {
  LMB_CHECK(!sparse_dir.empty(), "--sparse: missing");
  LMB_CHECK(!image_dir.empty(), "--images: missing");
  LMB_CHECK(!out_dir.empty(), "--out: missing");
  LMB_CHECK(gravity_file.empty() || up.empty(), "--gravity-file and --up are exclusive");
  if (!up.empty() && up != "auto") {
    try {
      parse_axis(up, "--up");
    } catch (const Error&) {
      LMB_FAIL("--up: '" << up << "' is neither an axis nor auto (expected +x, -x, +y, -y, +z, -z or auto)");
    }
  }
  parse_split_rule(split);
}

UpEstimate estimate_up_from_cameras(const std::vector<Rigid3d>& cam_from_world) {
  LMB_CHECK(!cam_from_world.empty(), "--up auto: no cameras to estimate the up axis from");
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Rigid3d& pose : cam_from_world) {
    sum += (pose.rotation.conjugate() * Eigen::Vector3d::UnitY()).normalized();  // camera +y in the world
  }
  const Eigen::Vector3d mean_down = sum / static_cast<double>(cam_from_world.size());
  LMB_CHECK(mean_down.norm() > 1e-6, "--up auto: the "
                                         << cam_from_world.size()
                                         << " cameras' down directions cancel out; give --up AXIS or a gravity file");
  UpEstimate e;
  e.up = -mean_down.normalized();
  e.cameras = static_cast<int>(cam_from_world.size());
  e.mean_resultant_length = mean_down.norm();
  static const std::array<const char*, 6> names = {"+x", "-x", "+y", "-y", "+z", "-z"};
  double best = -2.0;
  for (int a = 0; a < 6; ++a) {
    Eigen::Vector3d axis = Eigen::Vector3d::Zero();
    axis[a / 2] = a % 2 ? -1.0 : 1.0;
    const double c = e.up.dot(axis);
    if (c > best) {
      best = c;
      e.nearest_axis = names[a];
    }
  }
  e.nearest_axis_deg = std::acos(std::clamp(best, -1.0, 1.0)) * 180.0 / M_PI;
  return e;
}

std::optional<DepthStats> observed_point_depths(const ColmapModel& model) {
  std::map<int, const ColmapImage*> by_id;
  for (const ColmapImage& im : model.images) by_id[im.image_id] = &im;
  std::vector<double> depths;
  for (const ColmapPoint3D& p : model.points) {
    for (const ColmapTrackElement& e : p.track) {
      const auto it = by_id.find(e.image_id);
      if (it == by_id.end()) continue;
      const double z = (it->second->cam_from_world * p.xyz).z();
      if (z > 0) depths.push_back(z);
    }
  }
  if (depths.empty()) return std::nullopt;
  std::sort(depths.begin(), depths.end());
  const auto quantile = [&](double q) { return depths[static_cast<size_t>(q * (depths.size() - 1) + 0.5)]; };
  DepthStats d;
  d.observations = static_cast<int64_t>(depths.size());
  d.median = quantile(0.5);
  d.p95 = quantile(0.95);
  return d;
}
namespace {

// Each camera's size against its first image (in id order), decoded as the mapper will decode it:
// a wrong camera is an error now, not after the import (images sorted by id).
void check_camera_sizes(const ColmapModel& model, const fs::path& sparse_dir, const fs::path& image_dir) {
  std::set<int> seen;
  for (const ColmapImage& im : model.images) {
    if (!seen.insert(im.camera_id).second) continue;
    const fs::path path = image_dir / im.name;
    const cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
    LMB_CHECK(!image.empty(),
              "image " << im.image_id << " '" << im.name << "': " << path.string() << ": cannot decode the image");
    const Camera& camera = model.cameras.at(im.camera_id);
    LMB_CHECK(image.cols == camera.width && image.rows == camera.height,
              sparse_dir.string() << ": camera " << im.camera_id << " is " << camera.width << "x" << camera.height
                                  << " pixels, but its image " << path.string() << " is " << image.cols << "x"
                                  << image.rows);
  }
}

}  // namespace

ColmapImportStats import_colmap(const ColmapImportOptions& options) {
  options.check();
  ColmapFormat format = ColmapFormat::kText;
  const ColmapModel model = read_colmap_model(options.sparse_dir, &format);
  LMB_CHECK(!model.images.empty(), options.sparse_dir.string() << ": the sparse model has no image");
  check_collection_images(model, options.image_dir);
  check_camera_sizes(model, options.sparse_dir, options.image_dir);
  // The gravity file must cover every image of the model; lines of other images (photos the
  // reconstruction did not register) are skipped and counted.
  std::map<std::string, Eigen::Vector3d> gravity;
  std::vector<std::string> gravity_unused;
  if (!options.gravity_file.empty()) {
    gravity = read_gravity_file(options.gravity_file);
    std::map<std::string, Eigen::Vector3d> used;
    for (const ColmapImage& im : model.images) {
      const auto it = gravity.find(im.name);
      LMB_CHECK(it != gravity.end(), options.gravity_file.string() << ": no gravity for image " << im.name
                                                                   << " (image id " << im.image_id << ")");
      used.insert(*it);
    }
    for (const auto& [name, g] : gravity) {
      if (!used.count(name)) gravity_unused.push_back(name);
    }
    gravity = std::move(used);
  }

  std::vector<const ColmapImage*> order;
  for (const ColmapImage& im : model.images) order.push_back(&im);
  std::sort(order.begin(), order.end(), [](const ColmapImage* a, const ColmapImage* b) { return a->name < b->name; });
  std::vector<SplitFrame> frames;
  for (const ColmapImage* im : order) {
    SplitFrame f;
    f.keys = {im->name, fs::path(im->name).filename().string()};
    frames.push_back(f);
  }
  const std::vector<bool> is_map = assign_map_frames(parse_split_rule(options.split), frames, false);

  ColmapImportStats stats;
  stats.binary = format == ColmapFormat::kBinary;
  stats.depths = observed_point_depths(model);
  stats.gravity_lines_unused = gravity_unused;
  std::optional<Eigen::Vector3d> up;
  if (options.up == "auto") {
    std::vector<Rigid3d> poses;
    for (const ColmapImage& im : model.images) poses.push_back(im.cam_from_world);
    stats.up_estimate = estimate_up_from_cameras(poses);
    up = stats.up_estimate->up;
  } else if (!options.up.empty()) {
    up = parse_axis(options.up, "--up");
  }
  std::vector<CollectionImage> images;
  for (size_t i = 0; i < order.size(); ++i) {
    const ColmapImage& src = *order[i];
    CollectionImage out;
    out.image = src;
    out.image.points2d.clear();
    out.image.name = std::string(is_map[i] ? "map/" : "query/") + src.name;
    out.source = options.image_dir / src.name;
    if (!gravity.empty()) {
      out.gravity_in_cam = gravity.at(src.name);
    } else if (up) {
      out.gravity_in_cam = (src.cam_from_world.rotation * (-*up)).normalized();
    }
    (is_map[i] ? stats.map_frames : stats.query_frames) += 1;
    images.push_back(std::move(out));
  }
  stats.images = static_cast<int>(images.size());
  stats.has_gravity = images.front().gravity_in_cam.has_value();
  std::vector<MapSession> sessions;
  if (stats.map_frames > 0) sessions.push_back(MapSession{"map", SessionKind::kMap});
  if (stats.query_frames > 0) sessions.push_back(MapSession{"query", SessionKind::kQuery});
  write_collection(options.out_dir, model.cameras, images, options.overwrite, sessions);
  return stats;
}

}  // namespace lmb
