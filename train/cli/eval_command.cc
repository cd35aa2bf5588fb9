// `lboost eval`: LandmarkBoost and the descriptor-matching baselines on the same query frames of a
// map, as in the paper's experimental evaluation (train/eval/evaluation.h holds the protocol and
// the pipeline; this file parses the flags and writes the files). Writes report.json and prints
// the results table.
//
//   lboost eval --model model.lbm --map map.h5 --report report.json [--run RUN_DIR]
//               [--query-session NAME ...] [--keypoint-ranks ranks.json] [--methods a,b,...]
//               [--top-k 20] ...
//   lboost eval --bundle bundle.txt --map map.h5 --report report.json [--model model.lbm]
//               [--prior-noise 5 ...] [--no-prior]       (areas: docs/areas.md)
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/file_io.h"
#include "train/boost/train_config.h"
#include "train/cli/bundle_mode_options.h"
#include "train/cli/commands.h"
#include "train/eval/bundle_eval.h"
#include "train/eval/evaluation.h"
#include "train/eval/report.h"

namespace lmb::cli {

namespace {

void run_eval(const EvalOptions& options, const std::string& report_path, const std::string& run_dir,
              const std::string& keypoint_ranks) {
  const auto run_file = [&](const char* name) {
    return run_dir.empty() ? std::filesystem::path() : std::filesystem::path(run_dir) / name;
  };
  check_outputs_not_inputs({{report_path, "--report"}, {keypoint_ranks, "--keypoint-ranks"}},
                           {{options.model, "--model"},
                            {options.map, "--map"},
                            {options.vocab, "--vocab"},
                            {run_file("config.toml"), "--run"},
                            {run_file("summary.json"), "--run"}});
  LMB_CHECK(!options.methods.empty(), "eval: --methods is empty");
  EvalOptions o = options;
  if (!run_dir.empty()) {
    // The run's held-out map observations are ranked beside the query sessions.
    const std::filesystem::path config = std::filesystem::path(run_dir) / "config.toml";
    LMB_CHECK(std::filesystem::exists(config),
              "eval: --run " << run_dir << ": no config.toml (not a `lboost train` run dir)");
    o.training_set = read_run_train_config(config).training_set;
    o.run_dir = run_dir;
  }
  EvalResult result = run_evaluation(o);
  if (!run_dir.empty()) attach_training_summary(result.report, run_dir);
  write_report(report_path, result.report);
  if (!keypoint_ranks.empty()) write_report(keypoint_ranks, result.keypoint_ranks);
  std::printf("\n%s%s%s%s-> %s\n%s", result.heading.c_str(), result.table.c_str(), result.gap_table.c_str(),
              result.confidence_table.c_str(), report_path.c_str(), result.cpu_line.c_str());
}

// --bundle: pose recall of a bundle of area models with each prior mode and, with --model, of the
// single model, on the same frames and seeds (train/eval/bundle_eval.h).
void run_bundle_eval(const EvalOptions& o, BundleEvalOptions b, const std::string& report_path) {
  std::vector<NamedPath> inputs = bundle_input_paths(b.bundle, "--bundle");
  inputs.push_back({o.model, "--model"});
  inputs.push_back({o.map, "--map"});
  check_outputs_not_inputs({{report_path, "--report"}}, inputs);
  b.map = o.map;
  b.model = o.model;
  b.localizer.classifier.min_margin = o.min_margin;
  b.localizer.max_correspondences = o.max_correspondences;
  b.localizer.pose = o.pose;
  b.seeds = o.sweep.seeds;
  b.thresholds = o.pose_thresholds.at(0);
  const BundleEvalResult r = evaluate_bundle(b);
  write_report(report_path, r.report);
  warn_area_errors("eval", r.area_errors);
  std::printf("\nBundle %s on %zu query frames, %d RANSAC seeds, correct within %g m / %g deg:\n%s-> %s\n",
              b.bundle.c_str(), r.report.at("frames").get<size_t>(), b.seeds, b.thresholds.max_position_error_m,
              b.thresholds.max_rotation_error_deg, r.table.c_str(), report_path.c_str());
}

}  // namespace

void add_eval_command(CLI::App& app) {
  struct EvalArgs {
    EvalOptions options;
    BundleEvalOptions bundle;
    std::string report, run, keypoint_ranks;
    std::string pose_thresholds = "0.2,5";
  };
  auto args = std::make_shared<EvalArgs>();
  EvalOptions& o = args->options;
  std::string method_help = "Methods to run:";
  for (const EvalMethod& m : eval_methods()) {
    o.methods.push_back(m.name);
    method_help += "\n  " + m.name + ": " + m.description;
  }
  auto* cmd = app.add_subcommand(
      "eval", "LandmarkBoost and the descriptor baselines on the map's query frames: report.json + results table");
  cmd->add_option("--model", o.model, "Inference model (model.lbm); with --bundle, the single model compared")
      ->check(CLI::ExistingFile);
  cmd->add_option("--bundle", args->bundle.bundle,
                  "A bundle of area models (bundle.txt of `lboost bundle`): pose recall with --prior-noise and/or "
                  "--no-prior, and of --model on the same frames")
      ->check(CLI::ExistingFile);
  add_bundle_mode_options(cmd, &args->bundle);
  cmd->add_option("--map", o.map, "The map the model was trained on, with its query frames (map.h5)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--report", args->report,
                  "Output report (JSON; every field is described in the documentation's report page)")
      ->required();
  cmd->add_option("--run", args->run,
                  "Training run dir: its summary.json is copied into the report, and the observations it held "
                  "out of the map sessions (config.toml) are ranked beside the query sessions");
  cmd->add_option("--vocab", o.vocab,
                  "The vocabulary of training (.lbv): needed with a --run trained with --calibration-folds, whose "
                  "fold models every method's pose calibration is cross-fitted on")
      ->check(CLI::ExistingFile);
  cmd->add_option("--query-session", o.query_sessions,
                  "Query sessions to evaluate, by name (repeat or comma-separate; default: every session of kind "
                  "query; `lboost inspect` lists them)")
      ->delimiter(',');
  cmd->add_option("--keypoint-ranks", args->keypoint_ranks,
                  "Side file: every query keypoint's rank of its true landmark, per method");
  cmd->add_option("--methods", o.methods, method_help)->delimiter(',')->capture_default_str();
  cmd->add_option("--top-k", o.top_k, "Ranked landmarks per keypoint (MRR and miss-rate depth)")->capture_default_str();
  cmd->add_option("--inverted-file-words", o.inverted_file_words,
                  "landmarkboost_invfile: a keypoint's candidates are those of its N nearest words (1 = its own "
                  "word; 2 = multiple assignment, ~1.8x the candidates)")
      ->capture_default_str();
  cmd->add_option("--min-margin", o.min_margin,
                  "LandmarkBoost's background rejection: a keypoint's best match is accepted (fed to RANSAC) "
                  "only when its score beats the background's by more than this; the default 0 rejects, "
                  "-inf turns rejection off. P@1, MRR and miss rate always rank without rejection")
      ->capture_default_str();
  cmd->add_option("--max-correspondences", o.max_correspondences,
                  "Most confident matches fed to RANSAC, every method (0 = all)")
      ->capture_default_str();
  cmd->add_option("--ransac-iterations", o.pose.max_iterations, "RANSAC iterations")->capture_default_str();
  cmd->add_option("--max-error", o.pose.max_reprojection_error_px, "Inlier threshold, pixels")->capture_default_str();
  cmd->add_option("--min-inliers", o.pose.min_inliers, "Inliers for a pose")->capture_default_str();
  add_seed_option(cmd, "--seed", &o.pose.seed, "RANSAC seed (the same for every method)");
  cmd->add_flag("--uniform-sampling{false}", o.pose.progressive_sampling,
                "Uniform RANSAC sampling instead of PROSAC in each method's match order");
  cmd->add_option("--pose-thresholds", args->pose_thresholds,
                  "Pose recall at each METRES,DEGREES pair, ';'-separated (e.g. '0.2,5;1,2;0.05,1'); a frame "
                  "is correct (frames_correct, PR curve, sweep) within the first pair")
      ->capture_default_str();
  cmd->add_option("--ransac-sweep-iterations", o.sweep.iterations,
                  "Pose recall also at these RANSAC budgets, each over --ransac-sweep-seeds seeds")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--ransac-sweep-seeds", o.sweep.seeds, "Seeds of the sweep: --seed, --seed + 1, ...")
      ->capture_default_str();
  cmd->add_option("--calibration-frames", o.calibration.max_frames,
                  "Map frames each method's pose calibration is fitted on at most (every n-th map-session frame; "
                  "never a query)")
      ->capture_default_str();
  cmd->add_option("--target-precision", o.calibration.target_precision,
                  "Precision on the calibration poses each method's operating point is chosen for, in (0, 1]")
      ->capture_default_str();
  cmd->add_option("--max-elsewhere-share", o.calibration.max_elsewhere_share,
                  "Share of the calibration frames, matched as if nothing of their view were in the map, that each "
                  "method's operating point may still localize, in [0, 1]")
      ->capture_default_str();
  cmd->add_option("--ratio", o.ratio, "Lowe's ratio of the ratio-test methods: d1 < ratio * d2")->capture_default_str();
  cmd->add_option("--faiss-hnsw-m", o.faiss.m, "faiss_hnsw_ratio: HNSW graph degree M")->capture_default_str();
  cmd->add_option("--faiss-ef-construction", o.faiss.ef_construction, "faiss_hnsw_ratio: efConstruction")
      ->capture_default_str();
  cmd->add_option("--faiss-ef-search", o.faiss.ef_search,
                  "faiss_hnsw_ratio: efSearch (faiss searches with max(efSearch, 4 x --top-k))")
      ->capture_default_str();
  cmd->add_option("--hamming-backend", o.hamming_backend,
                  "bruteforce_hamming, hamming_ratio*: opencv (BFMatcher) or popcount")
      ->capture_default_str();
  cmd->add_option("--pca-dims", o.pca_dims, "projected_kdtree: PCA dimensions")->capture_default_str();
  cmd->callback([args] {
    args->options.pose_thresholds = parse_pose_thresholds(args->pose_thresholds, "eval: --pose-thresholds");
    if (!args->bundle.bundle.empty()) {
      run_bundle_eval(args->options, args->bundle, args->report);
      return;
    }
    LMB_CHECK(args->bundle.prior_noise.empty() && !args->bundle.no_prior && args->bundle.track.empty(),
              "eval: --prior-noise, --track and --no-prior need --bundle");
    LMB_CHECK(!args->options.model.empty(), "eval: --model is required (or --bundle)");
    run_eval(args->options, args->report, args->run, args->keypoint_ranks);
  });
}

}  // namespace lmb::cli
