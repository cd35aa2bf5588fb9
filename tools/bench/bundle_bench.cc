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
#include "train/cli/bundle_mode_options.h"
#include "train/cli/cli_util.h"
#include "train/eval/bundle_eval.h"

namespace lmb::bench {

namespace {

struct BenchBundleArgs {
  BundleEvalOptions options;
  std::string json;
};

// One tracking mode's line: the mean includes the frames relocalized (in every area or with the
// relocalization prior); the medians show a frame's usual cost and a tracked frame's.
void print_tracking_line(const nlohmann::json& t, double radius, double track_prior_noise, double single) {
  const double mean = t.at("cpu_ms_per_frame").at("mean").get<double>();
  const double median_all = t.at("cpu_ms_per_frame").at("median").get<double>();
  const nlohmann::json& tracked_median = t.at("cpu_ms_per_tracked_frame").at("median");  // null: none tracked
  const double median_tracked =
      tracked_median.is_number() ? tracked_median.get<double>() : std::numeric_limits<double>::quiet_NaN();
  const std::string relocalized_in =
      track_prior_noise < 0.0 ? std::string("in every area") : fmt::format("with a {:g} m prior", track_prior_noise);
  std::printf(
      "tracking %g m: %.2f ms mean (%.2fx the single model), median %.2f ms, tracked frames median %.2f ms "
      "(%.2fx the single model's mean); %.3f of the frames tracked, %.3f relocalized %s, %.2f areas "
      "scored\n",
      radius, mean, mean / single, median_all, median_tracked, median_tracked / single,
      t.at("tracked_per_frame").get<double>(), t.at("relocalized_per_frame").get<double>(), relocalized_in.c_str(),
      t.at("areas_scored_per_frame").get<double>());
}

void run_bench_bundle(BenchBundleArgs a) {
  std::vector<NamedPath> inputs = cli::bundle_input_paths(a.options.bundle, "--bundle");
  inputs.push_back({a.options.model, "--model"});
  inputs.push_back({a.options.map, "--map"});
  check_outputs_not_inputs({{a.json, "--json"}}, inputs);
  LMB_CHECK(!a.options.model.empty(), "--model (the single model to compare) is required");
  LMB_CHECK(!a.options.prior_noise.empty(), "--prior-noise: give at least one noise (metres)");
  a.options.no_prior = true;
  a.options.memory_per_area = false;
  const BundleEvalResult r = evaluate_bundle(a.options);
  cli::warn_area_errors("lboost-bench", "bundle", r.area_errors);
  // The modes in evaluate_bundle's order: one per prior noise, no prior, one per tracking radius,
  // the single model.
  const nlohmann::json& modes = r.report.at("modes");
  const size_t priors = a.options.prior_noise.size(), tracks = a.options.track.size();
  const auto ms = [&](size_t i) { return modes.at(i).at("cpu_ms_per_frame").at("mean").get<double>(); };
  const auto areas = [&](size_t i) { return modes.at(i).at("areas_scored_per_frame").get<double>(); };
  const size_t none_mode = priors, single_mode = priors + 1 + tracks;
  const double none = ms(none_mode), single = ms(single_mode);
  std::printf(
      "bench bundle (%s, %zu frames x %d seeds, single thread, thread CPU ms per frame): no prior %.2f ms (%.2f areas, "
      "%.2fx the single model), single model %.2f ms\n",
      machine_info().summary().c_str(), r.report.at("frames").get<size_t>(), a.options.seeds, none, areas(none_mode),
      none / single, single);
  for (size_t p = 0; p < priors; ++p) {
    std::printf("prior %g m: %.2f ms (%.2f areas scored, %.2fx the single model, no prior %.2fx it)\n",
                a.options.prior_noise[p], ms(p), areas(p), ms(p) / single, none / ms(p));
  }
  for (size_t t = 0; t < tracks; ++t) {
    print_tracking_line(modes.at(none_mode + 1 + t), a.options.track[t], a.options.track_prior_noise, single);
  }
  std::printf("%s", r.table.c_str());
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
  cmd->add_flag("--inverted-file", o.localizer.classifier.use_inverted_file,
                "Score only the keypoint word's candidate classes (every mode)");
  o.prior_noise = {5.0};
  cli::add_bundle_mode_options(cmd, &o);
  cmd->get_option("--prior-noise")->default_str("5");
  cmd->add_option("--repeats", o.seeds, "Passes over the frames (RANSAC seeds --seed, --seed + 1, ...)")
      ->capture_default_str();
  cli::add_seed_option(cmd, "--seed", &o.localizer.pose.seed, "First RANSAC seed");
  cmd->add_option("--json", args->json, "Also write the figures as JSON");
  cmd->callback([args] { run_bench_bundle(*args); });
}

}  // namespace lmb::bench
