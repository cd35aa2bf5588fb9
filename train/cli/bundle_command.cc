// lboost bundle: the index (bundle.txt) of a bundle of area models (infer/area_bundle.h,
// docs/areas.md) from the areas file and the areas' exported models.
//   lboost bundle --areas areas.txt --models DIR [--out DIR/bundle.txt]
// DIR holds area-ID.lbm for every area of the file (lboost export of each area's run); each must
// be a valid model whose classes are exactly its area's landmarks. With --map (the map the areas
// split), the bundle's pose calibration is fitted on map frames and written into the index.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/feature_space.h"
#include "common/file_container.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "infer/bundle_localizer.h"
#include "infer/model.h"
#include "infer/pose_confidence.h"
#include "train/areas/area_file.h"
#include "train/cli/commands.h"
#include "train/eval/bundle_calibration_fit.h"
#include "train/eval/bundle_eval.h"
#include "train/eval/landmarkboost_matcher.h"
#include "train/eval/metrics.h"
#include "train/eval/pose_calibration_fit.h"

namespace lmb::cli {

namespace {

struct BundleArgs {
  std::string areas;
  std::string models;
  std::string out;
  std::string map;               // optional: fit the bundle's calibration on its map frames
  int calibration_frames = 100;  // at most this many map frames
  bool inverted_file = false;    // localize them with the inverted file
  uint64_t seed = 0;             // RANSAC seed
  double target_precision = 0.95;
};

// Every area's model read and checked against its area (classes = the area's landmarks, in order).
std::vector<BundleArea> describe_areas(const AreaFile& file, const std::filesystem::path& dir) {
  std::vector<BundleArea> areas;
  for (const Area& area : file.split.areas) {
    const std::string name = "area-" + std::to_string(area.id) + ".lbm";
    const std::filesystem::path path = dir / name;
    const std::string what = path.string() + " (area " + std::to_string(area.id) + ")";
    std::string image;
    try {
      image = read_file(path);
    } catch (const Error& e) {
      LMB_FAIL("area " << area.id << ": " << e.what() << " (export the area's run there first)");
    }
    const auto model = Model::from_bytes(reinterpret_cast<const uint8_t*>(image.data()), image.size(), what);
    LMB_CHECK(model->num_classes() == static_cast<int32_t>(area.landmarks.size()),
              what << ": " << model->num_classes() << " classes, the area has " << area.landmarks.size()
                   << " landmarks (a model of another area or split?)");
    for (int32_t c = 0; c < model->num_classes(); ++c) {
      LMB_CHECK(model->class_landmark(c) == area.landmarks[static_cast<size_t>(c)],
                what << ": class " << c << " is landmark " << model->class_landmark(c) << ", the area's is "
                     << area.landmarks[static_cast<size_t>(c)] << " (a model of another area or split?)");
    }
    BundleArea a = describe_area(area.id, name, image, *model);
    a.cell_lo = area.cell.lo;
    a.cell_hi = area.cell.hi;
    areas.push_back(std::move(a));
  }
  return areas;
}

// Everything is read and checked (and the calibration fitted) before the index is written, once: a
// refused bundle leaves the index that was there as it was.
void run_bundle(const BundleArgs& args) {
  std::vector<NamedPath> inputs = area_model_paths(args.models, "--models");
  inputs.push_back({args.areas, "--areas"});
  inputs.push_back({args.map, "--map"});
  check_outputs_not_inputs({{args.out.empty() ? args.models + "/bundle.txt" : args.out, "--out"}}, inputs);
  namespace fs = std::filesystem;
  const fs::path dir(args.models);
  const fs::path out = args.out.empty() ? dir / "bundle.txt" : fs::path(args.out);
  LMB_CHECK(fs::weakly_canonical(out.parent_path()) == fs::weakly_canonical(dir),
            "--out " << out.string() << ": the index must sit in the --models folder " << dir.string()
                     << " (its model file names are relative to it)");
  LMB_CHECK(std::isfinite(args.target_precision) && args.target_precision >= 0.01 && args.target_precision <= 1.0,
            "--target-precision " << args.target_precision << " must be in 0.01..1");
  check_writable_file(out, "--out");
  const AreaFile file = read_area_file(args.areas);
  BundleIndex index;
  index.reach = file.split.options.reach;
  index.map_fingerprint = file.map_fingerprint;
  index.areas = describe_areas(file, dir);
  uint64_t total = 0;
  for (const BundleArea& a : index.areas) total += a.bytes;
  if (!args.map.empty()) {
    const LandmarkMap map = read_map_h5(args.map);
    LMB_CHECK(fingerprint_map(map) == file.map_fingerprint,
              "--map " << args.map << " is not the map " << args.areas << " splits (fingerprints differ)");
    check_area_file_map(file, args.areas, map);
    if (args.calibration_frames > 0) {
      if (const std::optional<BundleCalibration> fit =
              fit_bundle_calibration({args.calibration_frames, args.inverted_file, args.seed, args.target_precision},
                                     AreaBundle::create(out, index), file, map)) {
        index.calibration = fit->calibration;
        index.walk_calibration = fit->walk;
      }
    }
  }
  write_bundle_index(out, index);
  std::printf("bundle: %zu areas, %.1f MB of models, reach %.2f m%s -> %s\n", index.areas.size(),
              static_cast<double>(total) / 1048576.0, index.reach,
              index.calibration ? (index.walk_calibration ? ", calibrated (frames and walks)" : ", calibrated") : "",
              out.string().c_str());
}

}  // namespace

void add_bundle_command(CLI::App& app) {
  auto args = std::make_shared<BundleArgs>();
  auto* cmd = app.add_subcommand("bundle", "Index the areas' exported models as a bundle");
  cmd->add_option("--areas", args->areas, "areas file (lboost areas)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--models", args->models, "folder with area-ID.lbm for every area (lboost export)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", args->out, "the index, in the --models folder (default MODELS/bundle.txt)");
  cmd->add_option("--map", args->map,
                  "the map the areas split (map.h5): fit the bundle's pose and walk calibrations on its map frames")
      ->check(CLI::ExistingFile);
  cmd->add_option("--calibration-frames", args->calibration_frames,
                  "--map: map frames localized for the calibration at most (0 = no calibration)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--inverted-file", args->inverted_file,
                "--map: localize the calibration frames with the inverted file (as the bundle will be used)");
  add_seed_option(cmd, "--seed", &args->seed, "--map: RANSAC seed of the calibration frames");
  cmd->add_option("--target-precision", args->target_precision,
                  "--map: the operating point's precision on the calibration poses")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 1.0));
  cmd->callback([args] { run_bundle(*args); });
}

}  // namespace lmb::cli
