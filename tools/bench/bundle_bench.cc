// `lboost-bench bundle`: per-frame time of localization through a bundle of area models with a
// position prior, without a prior, tracking (--track), and of the single model, single thread, in the same run
// (train/eval/bundle_eval.h; docs/areas.md). Prints one line with the ratios.
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/file_io.h"
#include "common/machine_info.h"
#include "tools/bench/bench_commands.h"
#include "train/cli/cli_util.h"
#include "train/eval/bundle_eval.h"

namespace lmb::bench {

namespace {

struct BenchBundleArgs {
  BundleEvalOptions options;
  double prior_noise = 5.0;
  double track = 0.0;  // > 0: a tracking mode with this radius
  std::string json;
};

void run_bench_bundle(BenchBundleArgs a) {
  std::vector<NamedPath> inputs = cli::bundle_input_paths(a.options.bundle, "--bundle");
  inputs.push_back({a.options.model, "--model"});
  inputs.push_back({a.options.map, "--map"});
  check_outputs_not_inputs({{a.json, "--json"}}, inputs);
  LMB_CHECK(!a.options.model.empty(), "--model (the single model to compare) is required");
  a.options.prior_noise = {a.prior_noise};
  a.options.no_prior = true;
  if (a.track > 0.0) a.options.track = {a.track};
  a.options.memory_per_area = false;
  const BundleEvalResult r = evaluate_bundle(a.options);
  cli::warn_area_errors("lboost-bench", "bundle", r.area_errors);
  const nlohmann::json& modes = r.report.at("modes");
  const auto ms = [&](size_t i) { return modes.at(i).at("cpu_ms_per_frame").at("mean").get<double>(); };
  const size_t single_mode = a.track > 0.0 ? 3 : 2;  // prior, no prior, [tracking,] single
  const double prior = ms(0), none = ms(1), single = ms(single_mode);
  std::printf(
      "bench bundle (%s, %zu frames x %d seeds, single thread, thread CPU ms per frame): prior %g m %.2f ms "
      "(%.2f areas scored, %.2fx the single model), no prior %.2f ms (%.2f areas, %.2fx the single model, %.2fx the "
      "prior), single model %.2f ms\n%s",
      machine_info().summary().c_str(), r.report.at("frames").get<size_t>(), a.options.seeds, a.prior_noise, prior,
      modes.at(0).at("areas_scored_per_frame").get<double>(), prior / single, none,
      modes.at(1).at("areas_scored_per_frame").get<double>(), none / single, none / prior, single, r.table.c_str());
  if (a.track > 0.0) {
    // Tracking: the mean includes the frames relocalized in every area; the medians show a frame's
    // usual cost and a tracked frame's.
    const nlohmann::json& t = modes.at(2);
    const double median_all = t.at("cpu_ms_per_frame").at("median").get<double>();
    const nlohmann::json& tracked_median = t.at("cpu_ms_per_tracked_frame").at("median");  // null: none tracked
    const double median_tracked =
        tracked_median.is_number() ? tracked_median.get<double>() : std::numeric_limits<double>::quiet_NaN();
    const std::string relocalized_in = a.options.track_prior_noise < 0.0
                                           ? std::string("in every area")
                                           : fmt::format("with a {:g} m prior", a.options.track_prior_noise);
    std::printf(
        "tracking %g m: %.2f ms mean (%.2fx the single model), median %.2f ms, tracked frames median %.2f ms "
        "(%.2fx the single model's mean); %.3f of the frames tracked, %.3f relocalized %s, %.2f areas "
        "scored\n",
        a.track, ms(2), ms(2) / single, median_all, median_tracked, median_tracked / single,
        t.at("tracked_per_frame").get<double>(), t.at("relocalized_per_frame").get<double>(), relocalized_in.c_str(),
        t.at("areas_scored_per_frame").get<double>());
  }
  if (!a.json.empty())
    write_file_atomically(a.json, r.report.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
}

}  // namespace

void add_bundle_bench(CLI::App& app) {
  auto args = std::make_shared<BenchBundleArgs>();
  BundleEvalOptions& o = args->options;
  o.seeds = 3;
  auto* cmd = app.add_subcommand(
      "bundle", "Per-frame time through a bundle of area models with a prior, without one, and the single model");
  cmd->add_option("--bundle", o.bundle, "bundle.txt of `lboost bundle`")->required()->check(CLI::ExistingFile);
  cmd->add_option("--map", o.map, "Map whose query frames are localized (map.h5)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--model", o.model, "The single model compared (model.lbm)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--prior-noise", args->prior_noise, "Prior: true centre moved METRES, radius METRES")
      ->capture_default_str();
  cmd->add_option("--track", args->track,
                  "Also a tracking mode: the frames in capture order, the camera moving at most METRES a frame (0 = "
                  "none)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--tracking-areas", o.tracking_areas, "--track: areas scored before the motion gate judges")
      ->capture_default_str();
  cmd->add_option("--track-prior-noise", o.track_prior_noise,
                  "--track: relocalize with a position prior of this noise (as --prior-noise, e.g. a GPS fix) "
                  "instead of in every area (negative: every area)")
      ->capture_default_str();
  cmd->add_flag("--inverted-file", o.localizer.classifier.use_inverted_file,
                "Score only the keypoint word's candidate classes (every mode)");
  cmd->add_flag_function(
      "--winners-view", [args](int64_t) { args->options.search = AreaSearch::kWinnersView; },
      "With a prior: nearest area first, then the areas that see most of the current winning pose's view");
  cmd->add_option("--repeats", o.seeds, "Passes over the frames (RANSAC seeds --seed, --seed + 1, ...)")
      ->capture_default_str();
  cli::add_seed_option(cmd, "--seed", &o.localizer.pose.seed, "First RANSAC seed");
  cmd->add_option("--json", args->json, "Also write the figures as JSON");
  cmd->callback([args] { run_bench_bundle(*args); });
}

}  // namespace lmb::bench
