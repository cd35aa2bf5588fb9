#include "train/import/colmap_import.h"

#include <algorithm>

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
  if (!up.empty()) parse_axis(up, "--up");
  parse_split_rule(split);
}

ColmapImportStats import_colmap(const ColmapImportOptions& options) {
  options.check();
  ColmapFormat format = ColmapFormat::kText;
  const ColmapModel model = read_colmap_model(options.sparse_dir, &format);
  LMB_CHECK(!model.images.empty(), options.sparse_dir.string() << ": the sparse model has no image");
  check_collection_images(model, options.image_dir);
  std::map<std::string, Eigen::Vector3d> gravity;
  if (!options.gravity_file.empty()) gravity = read_gravity_file(options.gravity_file, model);

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
    } else if (!options.up.empty()) {
      out.gravity_in_cam = (src.cam_from_world.rotation * (-parse_axis(options.up, "--up"))).normalized();
    }
    (is_map[i] ? stats.map_frames : stats.query_frames) += 1;
    images.push_back(std::move(out));
  }
  stats.images = static_cast<int>(images.size());
  stats.has_gravity = images.front().gravity_in_cam.has_value();
  write_collection(options.out_dir, model.cameras, images, options.overwrite);
  return stats;
}

}  // namespace lmb
