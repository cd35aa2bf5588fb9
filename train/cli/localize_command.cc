// `lboost localize`: model.lbm + the query frames of a map (keypoints, descriptors, camera and
// gravity as the mapper detected them) -> poses and matches as JSON, and a summary against the
// map's ground-truth poses and keypoint landmarks. With --bundle (docs/areas.md): the query frames
// localized through a bundle of area models, with a noisy ground-truth prior and/or none.
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "common/landmark_map.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "train/cli/commands.h"
#include "train/eval/bundle_eval.h"
#include "train/eval/evaluation.h"
#include "train/eval/map_localization.h"

namespace lmb::cli {

namespace {

struct LocalizeArgs {
  std::string model;
  std::string map;
  std::vector<std::string> queries;  // frame names; empty = every query frame
  std::string out;
  LocalizerOptions options;
  int threads = 1;
  bool all_matches = false;
  BundleEvalOptions bundle;  // --bundle, --prior-noise, --no-prior, --prior-seed, --cache-areas
};

// --bundle: every query frame through the bundle in each prior mode (one RANSAC seed, one thread).
void run_bundle_localize(const LocalizeArgs& a) {
  LMB_CHECK(a.queries.empty(), "localize: --queries is not supported with --bundle (every query frame)");
  check_writable_file(a.out, "--out");
  BundleEvalOptions b = a.bundle;
  b.map = a.map;
  b.model = a.model;
  b.localizer = a.options;
  b.seeds = 1;
  b.memory_per_area = false;
  const BundleEvalResult r = evaluate_bundle(b);
  write_file_atomically(a.out, r.report.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  warn_area_errors("localize", r.area_errors);
  std::printf("localize: bundle %s, %zu query frames, seed %llu, correct within 0.2 m / 5 deg:\n%s-> %s\n",
              b.bundle.c_str(), r.report.at("frames").get<size_t>(),
              static_cast<unsigned long long>(a.options.pose.seed), r.table.c_str(), a.out.c_str());
}

void run_localize(const LocalizeArgs& a) {
  std::vector<NamedPath> inputs = bundle_input_paths(a.bundle.bundle, "--bundle");
  inputs.push_back({a.model, "--model"});
  inputs.push_back({a.map, "--map"});
  check_outputs_not_inputs({{a.out, "--out"}}, inputs);
  LMB_CHECK(a.threads >= 1 && a.threads <= 256, "localize: --threads = " << a.threads << " must be in 1..256");
  if (!a.bundle.bundle.empty()) {
    run_bundle_localize(a);
    return;
  }
  LMB_CHECK(a.bundle.prior_noise.empty() && !a.bundle.no_prior && a.bundle.track.empty(),
            "localize: --prior-noise, --track and --no-prior need --bundle");
  LMB_CHECK(!a.model.empty(), "localize: --model is required (or --bundle)");
  check_writable_file(a.out, "--out");
  const std::shared_ptr<const Model> model = Model::load(a.model);
  const LandmarkMap map = read_map_h5(a.map);
  const std::vector<char> is_class = check_model_fits_map(*model, a.model, map, a.map);
  MapLocalizationOptions o;
  o.localizer = a.options;
  o.queries = a.queries;
  o.threads = a.threads;
  o.all_matches = a.all_matches;
  nlohmann::json out = localize_map_frames(model, map, is_class, o);
  out["model"] = a.model;
  out["map"] = a.map;
  write_file_atomically(a.out, out.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  std::printf("%s -> %s\n", map_localization_summary_line(out.at("summary"), a.threads).c_str(), a.out.c_str());
}

}  // namespace

void add_localize_command(CLI::App& app) {
  auto args = std::make_shared<LocalizeArgs>();
  auto* cmd = app.add_subcommand("localize",
                                 "Localize the query frames of a map with model.lbm; write poses and matches as JSON");
  cmd->add_option("--model", args->model, "Inference model (model.lbm); with --bundle, the single model compared");
  cmd->add_option("--bundle", args->bundle.bundle,
                  "A bundle of area models (bundle.txt of `lboost bundle`), localized with --prior-noise and/or "
                  "--no-prior (docs/areas.md)");
  add_bundle_mode_options(cmd, &args->bundle);
  cmd->add_option("--map", args->map, "Map whose query frames are localized (map.h5)")->required();
  cmd->add_option("--queries", args->queries, "Frame names to localize (default: every query frame)");
  cmd->add_option("--out", args->out, "Output JSON (poses, matches, summary)")->required();
  cmd->add_option("--top-k", args->options.classifier.top_k, "Matches kept per keypoint")->capture_default_str();
  cmd->add_flag("--inverted-file", args->options.classifier.use_inverted_file,
                "Score only the keypoint word's candidate classes");
  cmd->add_option("--inverted-file-words", args->options.classifier.inverted_file_words,
                  "--inverted-file: the candidates of the keypoint's N nearest words (1 = its own word; 2 = "
                  "multiple assignment)")
      ->capture_default_str();
  cmd->add_option("--min-margin", args->options.classifier.min_margin,
                  "Background rejection: a match must beat the background's score by more than this "
                  "(-inf = no rejection)")
      ->capture_default_str();
  cmd->add_option("--pose-top-k", args->options.pose_top_k, "Matches per keypoint fed to RANSAC")
      ->capture_default_str();
  cmd->add_option("--max-correspondences", args->options.max_correspondences,
                  "Best-margin matches fed to RANSAC (0 = all)")
      ->capture_default_str();
  cmd->add_option("--ransac-iterations", args->options.pose.max_iterations, "RANSAC iterations")->capture_default_str();
  cmd->add_option("--max-error", args->options.pose.max_reprojection_error_px, "Inlier threshold, pixels")
      ->capture_default_str();
  cmd->add_option("--min-inliers", args->options.pose.min_inliers, "Inliers for a pose")->capture_default_str();
  cmd->add_option("--min-confidence", args->options.min_confidence,
                  "Calibrated probability a pose needs to count as localized (negative: the model's operating "
                  "point; ignored by an uncalibrated model)")
      ->capture_default_str();
  add_seed_option(cmd, "--seed", &args->options.pose.seed, "RANSAC seed");
  cmd->add_flag("--uniform-sampling{false}", args->options.pose.progressive_sampling,
                "Uniform RANSAC sampling instead of PROSAC in the order of the match margins");
  cmd->add_option("--threads", args->threads, "Frames localized in parallel")->capture_default_str();
  cmd->add_flag("--all-matches", args->all_matches, "Write every ranked match, not only the pose's");
  cmd->callback([args] { run_localize(*args); });
}

}  // namespace lmb::cli
