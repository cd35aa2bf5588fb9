// lboost import: posed images in other formats -> a collection for `lboost map`.
//   lboost import tum     a TUM RGB-D sequence (rgb.txt, groundtruth.txt, accelerometer.txt)
//   lboost import colmap  a COLMAP sparse model (text or binary) + its image folder
//   lboost import 7scenes video frames with camera-to-world poses (7-Scenes, 12-Scenes layout)
#include <array>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/file_io.h"
#include "train/cli/commands.h"
#include "train/import/colmap_import.h"
#include "train/import/sevenscenes_import.h"
#include "train/import/tum_import.h"
#include "train/import/visual_time_offset.h"

namespace lmb::cli {

namespace {

// The list file a --split rule reads (map-list:FILE, query-list:FILE, list:FILE), else "".
std::string split_list_file(const std::string& split) {
  const size_t colon = split.find(':');
  if (colon == std::string::npos) return "";
  const std::string kind = split.substr(0, colon);
  return kind == "list" || kind == "map-list" || kind == "query-list" ? split.substr(colon + 1) : "";
}

void print_gravity_agreement(const GravityAgreement& g, const std::string& world_up) {
  std::printf(
      "import: accelerometer vs ground-truth gravity (world up %s) over %d frames: median %.2f deg, "
      "mean %.2f deg, 90%% %.2f deg\n",
      world_up.c_str(), g.frames, g.median_deg, g.mean_deg, g.p90_deg);
  std::printf("import: median angle by world up axis: +x %.1f, -x %.1f, +y %.1f, -y %.1f, +z %.1f, -z %.1f deg\n",
              g.median_deg_by_world_axis[0], g.median_deg_by_world_axis[1], g.median_deg_by_world_axis[2],
              g.median_deg_by_world_axis[3], g.median_deg_by_world_axis[4], g.median_deg_by_world_axis[5]);
  std::printf(
      "import: best ground-truth time offset %+.3f s (median %.2f deg); fitted accelerometer rotation is "
      "%.2f deg from the assumed one (median %.2f deg after fitting)\n",
      g.best_time_offset_s, g.best_time_offset_median_deg, g.fitted_rotation_offset_deg, g.fitted_median_deg);
}

// Prints the visual time-offset scan (see train/import/visual_time_offset.h) of the sequence.
void run_time_offset_scan(const TumImportOptions& options) {
  spdlog::info("import tum: scanning the image/ground-truth time offset from the images (takes a minute or two)");
  const std::filesystem::path& dir = options.data_dirs.front();
  const std::vector<TumImage> images = read_tum_image_list(dir / "rgb.txt");
  const TumTrajectory trajectory = read_tum_trajectory(dir / "groundtruth.txt");
  const TimeOffsetScan scan = scan_time_offset_visual(dir, images, trajectory, parse_camera_line(options.camera), 0.05,
                                                      0.005, options.max_gap_s);
  std::printf("import: visual time offset scan over %d frame pairs (median relative-rotation disagreement):\n",
              scan.pairs);
  for (size_t k = 0; k < scan.offset_s.size(); ++k) {
    std::printf("import:   offset %+.3f s: %.3f deg (%d pairs)\n", scan.offset_s[k], scan.median_deg[k],
                scan.pairs_used[k]);
  }
  std::printf("import: best --time-offset %+.3f s\n", scan.best_offset_s);
}

void run_tum(const TumImportOptions& options, bool scan_offset) {
  std::vector<NamedPath> inputs = {{split_list_file(options.split), "--split"}};
  for (const auto& d : options.data_dirs) inputs.push_back({d, "--data", true});
  for (const auto& d : options.query_dirs) inputs.push_back({d, "--query-data", true});
  check_outputs_not_inputs({{options.out_dir, "--out", true}}, inputs);
  std::string sources;
  for (const auto& d : options.data_dirs) sources += (sources.empty() ? "" : ", ") + d.string();
  for (const auto& d : options.query_dirs) sources += (sources.empty() ? "" : ", ") + d.string() + " (query)";
  spdlog::info("import tum: {} -> {}", sources, options.out_dir.string());
  const TumImportStats s = import_tum(options);
  std::printf(
      "import: %d frames listed, %d imported (%d map, %d query), %d skipped without ground truth within "
      "%.0f ms, %d skipped without accelerometer\n",
      s.listed_frames, s.imported_frames, s.map_frames, s.query_frames, s.skipped_no_pose, options.max_gap_s * 1000,
      s.skipped_no_accelerometer);
  std::string session_list;
  for (size_t i = 0; i < s.sessions.size(); ++i) {
    session_list += (i ? ", " : "") + s.sessions[i].name + " (" + session_kind_name(s.sessions[i].kind) + ", " +
                    std::to_string(s.session_frames[i]) + " frames)";
  }
  std::printf("import: sessions: %s\n", session_list.c_str());
  if (s.gravity_agreement) print_gravity_agreement(*s.gravity_agreement, options.world_up);
  std::printf("import: wrote %s (sparse/, sessions.txt, images/ -> %s%s)\n", options.out_dir.string().c_str(),
              sources.c_str(), options.gravity == "none" ? "" : ", gravity.txt");
  if (scan_offset) run_time_offset_scan(options);
}

void run_colmap(const ColmapImportOptions& options) {
  check_outputs_not_inputs({{options.out_dir, "--out", true}}, {{options.sparse_dir, "--sparse", true},
                                                                {options.image_dir, "--images", true},
                                                                {options.gravity_file, "--gravity-file"},
                                                                {split_list_file(options.split), "--split"}});
  spdlog::info("import colmap: {} + {} -> {}", options.sparse_dir.string(), options.image_dir.string(),
               options.out_dir.string());
  const ColmapImportStats s = import_colmap(options);
  if (s.depths) {
    std::printf(
        "import: the model's 3D points lie at depth median %.3g, 95th percentile %.3g (model units, %lld "
        "observations); lboost map --max-depth (default 40, same units) must cover the scene\n",
        s.depths->median, s.depths->p95, static_cast<long long>(s.depths->observations));
  }
  if (s.up_estimate) {
    const UpEstimate& e = *s.up_estimate;
    std::printf(
        "import: --up auto: up = (%.4f, %.4f, %.4f), minus the mean image down direction (camera +y) of %d "
        "cameras (mean resultant length %.3f; 1 = all parallel); nearest world axis %s, %.1f deg away\n",
        e.up.x(), e.up.y(), e.up.z(), e.cameras, e.mean_resultant_length, e.nearest_axis.c_str(), e.nearest_axis_deg);
    if (e.mean_resultant_length < 0.5) {
      std::printf(
          "import: warning: the cameras' down directions disagree (mean resultant length %.3f < 0.5): the "
          "estimate assumes upright cameras; prefer a gravity file or a known --up AXIS\n",
          e.mean_resultant_length);
    }
  }
  if (!s.gravity_lines_unused.empty()) {
    std::printf("import: %s: %zu lines name no image of the model (not registered?), e.g. %s: skipped\n",
                options.gravity_file.string().c_str(), s.gravity_lines_unused.size(),
                s.gravity_lines_unused.front().c_str());
  }
  std::printf("import: %s model, %d images (%d map, %d query), %s; wrote %s\n", s.binary ? "binary" : "text", s.images,
              s.map_frames, s.query_frames, s.has_gravity ? "gravity.txt written" : "no gravity file",
              options.out_dir.string().c_str());
}

void run_sevenscenes(const SevenScenesImportOptions& options) {
  check_outputs_not_inputs({{options.out_dir, "--out", true}},
                           {{options.data_dir, "--data", true},
                            {options.intrinsics_file, "--intrinsics"},
                            {options.gravity == "none" ? std::string() : options.gravity, "--gravity"}});
  spdlog::info("import 7scenes: {} -> {}", options.data_dir.string(), options.out_dir.string());
  const SevenScenesImportStats s = import_sevenscenes(options);
  std::string skipped;
  for (size_t i = 0; i < s.skipped_poses.size() && i < 5; ++i) {
    skipped += (i ? ", " : ": ") + std::filesystem::path(s.skipped_poses[i]).filename().string();
  }
  if (s.skipped_poses.size() > 5) skipped += ", ...";
  std::printf(
      "import: %s (%s): %d frames selected, %d imported (%d map, %d query), %d skipped for a non-finite pose%s\n",
      options.data_dir.string().c_str(), s.layout.c_str(), s.selected_frames, s.imported_frames, s.map_frames,
      s.query_frames, s.skipped_invalid_pose, skipped.c_str());
  const std::vector<double>& p = s.camera.params;
  std::printf("import: camera PINHOLE %dx%d, fx %g, fy %g, cx %g, cy %g, from %s\n", s.camera.width, s.camera.height,
              p[0], p[1], p[2], p[3], s.camera_source.c_str());
  if (s.gravity_down_world) {
    const Eigen::Vector3d& g = *s.gravity_down_world;
    std::printf(
        "import: gravity: down (%.4f, %.4f, %.4f) in the world, from %s; the cameras' image down axes (camera +y) "
        "lie a median %.1f deg from it (10%%-90%%: %.1f-%.1f deg)\n",
        g.x(), g.y(), g.z(), s.gravity_source.c_str(), s.image_down_median_deg, s.image_down_p10_deg,
        s.image_down_p90_deg);
    if (s.image_down_median_deg > 90) {
      std::printf(
          "import: warning: the cameras' image down axes point away from that gravity vector (median %.1f deg > 90): "
          "it may point up; check it, or give --gravity-up X Y Z\n",
          s.image_down_median_deg);
    }
  } else {
    std::printf("import: gravity: %s; lboost map then needs --up AXIS\n", s.gravity_source.c_str());
  }
  std::string session_list;
  for (size_t i = 0; i < s.sessions.size(); ++i) {
    session_list += (i ? ", " : "") + s.sessions[i].name + " (" + session_kind_name(s.sessions[i].kind) + ", " +
                    std::to_string(s.session_frames[i]) + " frames)";
  }
  std::printf("import: sessions: %s\n", session_list.c_str());
  std::printf("import: wrote %s (sparse/, sessions.txt, images/ -> %s%s)\n", options.out_dir.string().c_str(),
              options.data_dir.string().c_str(), s.gravity_down_world ? ", gravity.txt" : "");
}

void add_import_tum(CLI::App* cmd) {
  auto tum = std::make_shared<TumImportOptions>();
  auto tum_data = std::make_shared<std::vector<std::string>>();
  auto tum_query = std::make_shared<std::vector<std::string>>();
  auto tum_out = std::make_shared<std::string>();
  auto* t = cmd->add_subcommand(
      "tum", "TUM RGB-D sequences (rgb.txt, groundtruth.txt, accelerometer.txt, rgb/), one session each");
  t->add_option("--data", *tum_data,
                "Map sequence folder; repeat it to join several sequences of one place (each its own map "
                "session, split by --split)")
      ->required();
  t->add_option("--query-data", *tum_query,
                "Query sequence folder (repeatable): every frame a query frame, its own query session");
  t->add_option("--names", tum->session_names,
                "Session names, one per sequence (--data ones, then --query-data ones; default: the folders' "
                "names, or map and query for a single sequence)")
      ->delimiter(',');
  t->add_option("--out", *tum_out, "Collection folder to write (sparse/, images/ with symlinks, gravity.txt)")
      ->required();
  t->add_option("--split", tum->split,
                "Map/query split of each map sequence's frames: every:N (frames 0, N, 2N.. map), first:F, "
                "time:A:B (seconds from the sequence's first frame), map-list:FILE (FILE names the map frames), "
                "query-list:FILE (FILE names the query frames); list:FILE = map-list:FILE")
      ->capture_default_str();
  t->add_option("--gravity", tum->gravity, "gravity.txt from: accelerometer, groundtruth-up, none")
      ->check(CLI::IsMember({"accelerometer", "groundtruth-up", "none"}))
      ->capture_default_str();
  t->add_option("--world-up", tum->world_up, "Up axis of the ground-truth world (groundtruth-up and the check)")
      ->capture_default_str();
  t->add_option("--time-offset", tum->time_offset_s,
                "Seconds added to image timestamps to look up ground truth (positive: ground truth lags)")
      ->capture_default_str();
  t->add_option("--max-gap", tum->max_gap_s, "Frames without ground truth this close (s) are skipped")
      ->capture_default_str();
  t->add_option("--accel-window", tum->accel_half_window_s, "Half-width (s) of the accelerometer average")
      ->capture_default_str();
  t->add_option("--camera", tum->camera, "Camera as 'MODEL WIDTH HEIGHT PARAMS...' (COLMAP)")->capture_default_str();
  t->add_flag("--overwrite", tum->overwrite,
              "Replace sparse/, images/, gravity.txt and sessions.txt of an existing output");
  auto scan_offset = std::make_shared<bool>(false);
  t->add_flag("--estimate-time-offset", *scan_offset,
              "Also measure the image/ground-truth time offset from the images (+-50 ms in 5 ms steps)");
  t->callback([tum, tum_data, tum_query, tum_out, scan_offset] {
    TumImportOptions options = *tum;
    options.data_dirs.assign(tum_data->begin(), tum_data->end());
    options.query_dirs.assign(tum_query->begin(), tum_query->end());
    options.out_dir = *tum_out;
    run_tum(options, *scan_offset);
  });
}

void add_import_colmap(CLI::App* cmd) {
  auto colmap = std::make_shared<ColmapImportOptions>();
  auto paths = std::make_shared<std::array<std::string, 4>>();
  auto* c = cmd->add_subcommand("colmap", "A COLMAP sparse model (text or binary) and its image folder");
  c->add_option("--sparse", (*paths)[0], "Sparse model folder (cameras/images .bin or .txt)")->required();
  c->add_option("--images", (*paths)[1], "Image folder the model's image names are relative to")->required();
  c->add_option("--out", (*paths)[2], "Collection folder to write")->required();
  c->add_option("--split", colmap->split,
                "Map/query split over the images sorted by name: every:N, first:F, map-list:FILE (FILE names "
                "the map images), query-list:FILE (FILE names the query images); list:FILE = map-list:FILE")
      ->capture_default_str();
  c->add_option("--gravity-file", (*paths)[3],
                "Per-image gravity (IMAGE_NAME gx gy gz, camera frame, down): a line for every image of the "
                "model; lines of other images are skipped");
  c->add_option("--up", colmap->up,
                "Or: the model's world up axis (+x, -x, +y, -y, +z, -z) for gravity.txt; 'auto' estimates it "
                "from the cameras (minus their mean image down direction) and reports the nearest axis");
  c->add_flag("--overwrite", colmap->overwrite,
              "Replace sparse/, images/, gravity.txt and sessions.txt of an existing output");
  c->callback([colmap, paths] {
    ColmapImportOptions options = *colmap;
    options.sparse_dir = (*paths)[0];
    options.image_dir = (*paths)[1];
    options.out_dir = (*paths)[2];
    options.gravity_file = (*paths)[3];
    run_colmap(options);
  });
}

void add_import_sevenscenes(CLI::App* cmd) {
  auto scenes = std::make_shared<SevenScenesImportOptions>();
  auto scene_paths = std::make_shared<std::array<std::string, 4>>();  // data, out, intrinsics, gravity
  auto camera = std::make_shared<std::array<double, 3>>();            // focal, cx, cy
  auto up = std::make_shared<std::vector<double>>();
  auto* v = cmd->add_subcommand(
      "7scenes",
      "Video frames with camera-to-world poses in the 7-Scenes / 12-Scenes layout (frame-NNNNNN.color.png or "
      ".jpg, frame-NNNNNN.pose.txt)");
  v->add_option("--data", (*scene_paths)[0],
                "Data folder: rgb/ and pose/ folders, the frames themselves, or sequence folders (seq-01/, ...)")
      ->required();
  v->add_option("--out", (*scene_paths)[1], "Collection folder to write (sparse/, images/ with symlinks, gravity.txt)")
      ->required();
  v->add_option("--map-frames", scenes->map_frames,
                "Map frames: frame numbers FIRST-LAST or N, sequence folders NAME or NAME:FIRST-LAST, comma "
                "separated (e.g. 0-499, or seq-01,seq-02)")
      ->required();
  v->add_option("--query-frames", scenes->query_frames, "Query frames, as --map-frames (e.g. 500-999, or seq-03)");
  v->add_option("--stride", scenes->stride, "Keep every N-th frame of each item (FIRST, FIRST + N, ...)")
      ->capture_default_str();
  v->add_option("--intrinsics", (*scene_paths)[2],
                "Camera matrix file (3 rows: fx 0 cx / 0 fy cy / 0 0 1); default DATA/camera-intrinsics.txt");
  auto* focal = v->add_option("--focal", (*camera)[0], "Focal length in pixels (fx = fy), instead of a K file");
  auto* cx = v->add_option("--cx", (*camera)[1], "Principal point x in pixels (with --focal; default: image centre)");
  auto* cy = v->add_option("--cy", (*camera)[2], "Principal point y in pixels (with --focal; default: image centre)");
  v->add_option("--gravity", (*scene_paths)[3],
                "World-frame gravity vector file (3 numbers, pointing down) for gravity.txt, or none; default "
                "DATA/gravity-direction.txt when present");
  v->add_option("--gravity-up", *up, "The world's up direction X Y Z instead of a gravity file")->expected(3);
  v->add_flag("--overwrite", scenes->overwrite,
              "Replace sparse/, images/, gravity.txt and sessions.txt of an existing output");
  v->callback([scenes, scene_paths, camera, up, focal, cx, cy] {
    SevenScenesImportOptions options = *scenes;
    options.data_dir = (*scene_paths)[0];
    options.out_dir = (*scene_paths)[1];
    options.intrinsics_file = (*scene_paths)[2];
    options.gravity = (*scene_paths)[3];
    if (focal->count()) options.focal = (*camera)[0];
    if (cx->count()) options.cx = (*camera)[1];
    if (cy->count()) options.cy = (*camera)[2];
    if (!up->empty()) options.gravity_up = Eigen::Vector3d((*up)[0], (*up)[1], (*up)[2]);
    run_sevenscenes(options);
  });
}

}  // namespace

void add_import_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("import", "Turn posed images in other formats into a collection");
  cmd->require_subcommand(1);
  add_import_tum(cmd);
  add_import_colmap(cmd);
  add_import_sevenscenes(cmd);
}

}  // namespace lmb::cli
