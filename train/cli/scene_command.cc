// `lboost scene`: map.h5 (and the poses of `lboost localize`) -> OUT/sparse, a COLMAP text model of
// the landmarks, map frames and localized photos, and OUT/scene.ply, a coloured point cloud of the
// landmarks and camera centres (train/cli/map_scene.h; docs/localize_photos.md shows them).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "train/cli/commands.h"
#include "train/cli/map_scene.h"

namespace lmb::cli {

namespace {

struct SceneArgs {
  std::string map;
  std::string poses;
  std::string images;
  std::string out;
};

void run_scene(const SceneArgs& a) {
  namespace fs = std::filesystem;
  check_outputs_not_inputs({{a.out, "--out", true}},
                           {{a.map, "--map"}, {a.poses, "--poses"}, {a.images, "--images", true}});
  LMB_CHECK(a.images.empty() || fs::is_directory(a.images), "--images " << a.images << ": not a folder");
  check_writable_folder(a.out, "--out");
  const LandmarkMap map = read_map_h5(a.map);
  const std::vector<ScenePhoto> photos =
      a.poses.empty() ? std::vector<ScenePhoto>() : read_localized_poses(a.poses, map);
  SceneStats stats;
  const ColmapModel model = map_scene_model(map, photos, a.images, &stats);
  const size_t map_images = model.images.size() - photos.size();
  const fs::path out(a.out);
  write_colmap_text(model, out / "sparse");
  write_scene_ply(model, map_images, out / "scene.ply");
  const std::string missing = stats.images_missing > 0
                                  ? ", " + std::to_string(stats.images_missing) + " map frames without a readable image"
                                  : std::string();
  std::printf(
      "scene: %zu landmarks (%lld coloured from %lld map frame images%s), %zu map frames, %zu localized photos -> "
      "%s (COLMAP text), %s\n",
      model.points.size(), static_cast<long long>(stats.coloured_landmarks), static_cast<long long>(stats.images_read),
      missing.c_str(), map_images, photos.size(), (out / "sparse").string().c_str(),
      (out / "scene.ply").string().c_str());
}

}  // namespace

void add_scene_command(CLI::App& app) {
  auto args = std::make_shared<SceneArgs>();
  auto* cmd = app.add_subcommand(
      "scene", "Write a map and localized poses as a COLMAP text model and a PLY point cloud, to view them");
  cmd->add_option("--map", args->map, "The map (map.h5): its landmarks and map frames")->required();
  cmd->add_option("--poses", args->poses,
                  "Poses of `lboost localize` (--image/--images or --map): its localized photos or frames are "
                  "added as images without 2D points, named localized/NAME");
  cmd->add_option("--images", args->images,
                  "The collection's image folder (the map frames' names are relative to it): each landmark takes "
                  "the mean colour of the pixels it was seen at; without it landmarks are grey");
  cmd->add_option("--out", args->out,
                  "Output folder: OUT/sparse (cameras.txt, images.txt, points3D.txt; POINT3D_ID = landmark id + 1) "
                  "and OUT/scene.ply (landmarks in their colour, map frame centres blue, localized camera centres "
                  "red)")
      ->required();
  cmd->callback([args] { run_scene(*args); });
}

}  // namespace lmb::cli
