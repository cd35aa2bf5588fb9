// lboost areas: splits a map into overlapping areas of at most K landmark classes each, one
// classifier per area (train/areas/area_split.h, docs/areas.md), and writes the areas file.
//   lboost areas --map map.h5 --out areas.txt [--max-classes K] [--min-observations N]
//                [--overlap METRES] [--prior-noise METRES ...]
//                [--reach METRES]
// With --prior-noise it also reports how well the areas a position prior of that noise selects
// cover the query frames' keypoints (their true landmarks).
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/feature_space.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "train/areas/area_file.h"
#include "train/areas/area_split.h"
#include "train/cli/commands.h"

namespace lmb::cli {

namespace {

struct AreasArgs {
  std::string map;
  std::string out;
  AreaSplitOptions options;
  std::vector<double> prior_noise;
  uint64_t seed = 1;
};

void run_areas(const AreasArgs& args) {
  check_outputs_not_inputs({{args.out, "--out"}}, {{args.map, "--map"}});
  args.options.check();
  for (double noise : args.prior_noise) {
    LMB_CHECK(std::isfinite(noise) && noise >= 0.0, "--prior-noise " << noise << ": must be finite and >= 0");
  }
  check_writable_file(args.out, "--out");
  const LandmarkMap map = read_map_h5(args.map);
  AreaFile file;
  file.split = split_map_into_areas(map, args.options);
  file.map_fingerprint = fingerprint_map(map);
  file.map_landmarks = static_cast<int64_t>(map.landmarks.size());
  const AreaSplit& split = file.split;
  const std::vector<landmark_t> uncovered = uncovered_landmarks(map, split);
  write_area_file(args.out, file, "lboost areas of " + std::filesystem::absolute(args.map).lexically_normal().string());

  int64_t total = 0, truncated = 0;
  size_t largest = 0;
  for (const Area& a : split.areas) {
    total += static_cast<int64_t>(a.landmarks.size());
    truncated += a.num_truncated;
    largest = std::max(largest, a.landmarks.size());
    std::printf(
        "areas: area %d: %zu landmarks (%lld in its cell)%s, landmarks x %.2f..%.2f y %.2f..%.2f "
        "z %.2f..%.2f\n",
        a.id, a.landmarks.size(), static_cast<long long>(a.num_core),
        a.num_truncated ? (", " + std::to_string(a.num_truncated) + " overlap landmarks left out").c_str() : "",
        a.bounds.lo.x(), a.bounds.hi.x(), a.bounds.lo.y(), a.bounds.hi.y(), a.bounds.lo.z(), a.bounds.hi.z());
  }
  std::printf(
      "areas: %zu areas of at most %d classes (largest %zu), %lld eligible landmarks (>= %d map "
      "observations), %lld uncovered, %.2f areas per landmark, overlap %g m, reach %.2f m -> %s\n",
      split.areas.size(), split.options.max_classes, largest, static_cast<long long>(split.num_eligible),
      split.options.min_observations, static_cast<long long>(uncovered.size()),
      static_cast<double>(total) / static_cast<double>(split.num_eligible - uncovered.size()), split.options.overlap,
      split.options.reach, args.out.c_str());
  if (truncated > 0) {
    std::printf(
        "areas: warning: %lld overlap landmarks left out of areas whose landmarks cannot be halved "
        "(raise --max-classes or lower --overlap)\n",
        static_cast<long long>(truncated));
  }
  for (double noise : args.prior_noise) {
    const AreaCoverage c = query_coverage(map, split, noise, args.seed);
    const double n = static_cast<double>(std::max<int64_t>(1, c.num_keypoints));
    std::printf(
        "areas: prior noise %g m: %d query frames, %.2f areas selected per frame (max %d); of %lld query "
        "keypoints with a true landmark (%.1f%% eligible) %.1f%% are in a selected area, %.1f%% in the "
        "frame's best one\n",
        noise, c.num_query_frames, c.mean_selected_areas, c.max_selected_areas, static_cast<long long>(c.num_keypoints),
        100.0 * static_cast<double>(c.num_eligible) / n, 100.0 * static_cast<double>(c.num_covered_any) / n,
        100.0 * static_cast<double>(c.num_covered_best) / n);
  }
}

}  // namespace

void add_areas_command(CLI::App& app) {
  auto args = std::make_shared<AreasArgs>();
  auto* cmd = app.add_subcommand("areas", "Split a map into overlapping areas, one classifier each");
  cmd->add_option("--map", args->map, "map file (lboost map)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", args->out, "areas file (text), written atomically")->required();
  cmd->add_option("--max-classes", args->options.max_classes, "landmark classes per area at most")
      ->capture_default_str();
  cmd->add_option("--min-observations", args->options.min_observations,
                  "landmarks with at least this many map observations are covered by some area")
      ->capture_default_str();
  cmd->add_option("--overlap", args->options.overlap,
                  "landmarks this close (world units, metres) to an area's cell join it too")
      ->capture_default_str();
  cmd->add_option("--reach", args->options.reach,
                  "how far cameras see (metres): a prior selects the areas within its radius plus this; "
                  "0 = the 90th percentile of the map's observation distances")
      ->capture_default_str();
  cmd->add_option("--prior-noise", args->prior_noise,
                  "report the query keypoints covered by the areas a position prior this far (metres) from "
                  "the true camera selects; repeatable");
  add_seed_option(cmd, "--seed", &args->seed, "seed of the prior directions");
  cmd->callback([args] { run_areas(*args); });
}

}  // namespace lmb::cli
