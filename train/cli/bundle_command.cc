// lboost bundle: the index (bundle.txt) of a bundle of area models (infer/area_bundle.h,
// docs/areas.md) from the areas file and the areas' exported models.
//   lboost bundle --areas areas.txt --models DIR [--out DIR/bundle.txt]
// DIR holds area-ID.lbm for every area of the file (lboost export of each area's run); each must
// be a valid model whose classes are exactly its area's landmarks.
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/file_container.h"
#include "common/file_io.h"
#include "infer/area_bundle.h"
#include "infer/model.h"
#include "train/areas/area_file.h"
#include "train/cli/commands.h"
#include "train/eval/bundle_eval.h"

namespace lmb::cli {

namespace {

struct BundleArgs {
  std::string areas;
  std::string models;
  std::string out;
};

void run_bundle(const BundleArgs& args) {
  namespace fs = std::filesystem;
  const fs::path dir(args.models);
  const fs::path out = args.out.empty() ? dir / "bundle.txt" : fs::path(args.out);
  LMB_CHECK(fs::weakly_canonical(out.parent_path()) == fs::weakly_canonical(dir),
            "--out " << out.string() << ": the index must sit in the --models folder " << dir.string()
                     << " (its model file names are relative to it)");
  check_writable_file(out, "--out");
  const AreaFile file = read_area_file(args.areas);
  std::vector<BundleArea> areas;
  uint64_t total = 0;
  for (const Area& area : file.split.areas) {
    BundleArea a;
    a.id = area.id;
    a.file = "area-" + std::to_string(area.id) + ".lbm";
    const fs::path path = dir / a.file;
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
    a.bytes = image.size();
    a.crc32 = crc32(reinterpret_cast<const uint8_t*>(image.data()), image.size());
    a.landmarks = static_cast<int64_t>(area.landmarks.size());
    a.cell_lo = area.cell.lo;
    a.cell_hi = area.cell.hi;
    total += a.bytes;
    areas.push_back(a);
  }
  write_bundle_index(out, file.split.options.reach, areas);
  std::printf("bundle: %zu areas, %.1f MB of models, reach %.2f m -> %s\n", areas.size(),
              static_cast<double>(total) / 1048576.0, file.split.options.reach, out.string().c_str());
}

}  // namespace

void add_bundle_command(CLI::App& app) {
  auto args = std::make_shared<BundleArgs>();
  auto* cmd = app.add_subcommand("bundle", "Index the areas' exported models as a bundle (docs/areas.md)");
  cmd->add_option("--areas", args->areas, "areas file (lboost areas)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--models", args->models, "folder with area-ID.lbm for every area (lboost export)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", args->out, "the index, in the --models folder (default MODELS/bundle.txt)");
  cmd->callback([args] { run_bundle(*args); });
}

void add_bundle_mode_options(CLI::App* cmd, BundleEvalOptions* options) {
  cmd->add_option("--prior-noise", options->prior_noise,
                  "--bundle: a position prior per query frame, its true centre moved METRES in a seeded direction, "
                  "radius METRES (repeatable)");
  cmd->add_flag("--no-prior", options->no_prior, "--bundle: localize in every area, without a prior");
  cmd->add_flag_function(
      "--all-areas", [options](int64_t) { options->search = AreaSearch::kAll; },
      "--bundle: with a prior, score every selected area (default: nearest area first, the first calibrated "
      "localized pose wins)");
  cmd->add_option("--area-winner", options->winner,
                  "--bundle: which scored area's pose wins: support (explains most keypoints with every scored "
                  "area's matches) or inliers (most inliers of its own area)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, AreaWinner>{{"support", AreaWinner::kSupport}, {"inliers", AreaWinner::kInliers}}))
      ->default_str("support");
  cmd->add_option("--prior-seed", options->prior_seed, "--bundle: seed of the prior's direction")
      ->capture_default_str();
  cmd->add_option("--cache-areas", options->cache.max_areas,
                  "--bundle: at most this many areas loaded (least recently used freed first; 0 = no limit)")
      ->capture_default_str();
}

}  // namespace lmb::cli
