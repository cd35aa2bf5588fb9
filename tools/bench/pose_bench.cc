// `lboost-bench pose`: the project's pose estimator (infer/pose_estimator.h: P3P in the loop of
// infer/ransac.h) at several settings on the same correspondences, in one run. Each query frame of
// a map with ground truth is classified once by the model (the Localizer's correspondences and
// their margins over the background); then, for each RANSAC seed, frame by frame, every setting
// estimates the pose from them:
//   plain_ransac       the same loop as plain RANSAC: uniform samples, the best minimal model as it
//                      is (no local optimisation, no final refinement); --plain-iterations samples
//   lo_ransac_prosac   estimate_absolute_pose with the Localizer's settings: PROSAC in the margin
//                      order and local optimisation; --iterations samples, then each other budget
//                      of --budgets
//   lo_ransac_uniform  the same with uniform samples (what the margin order brings); --iterations
// Reported per setting: pose recall (within 20 cm / 5 deg, over the query frames) per seed with
// mean and range, thread CPU milliseconds of the pose step per frame and its ratio against
// plain_ransac in the same run, and the loop's samples (P3P calls), models scored and local
// optimisations per frame.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "common/machine_info.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "infer/pose_estimator.h"
#include "tools/bench/bench_commands.h"
#include "train/eval/timing.h"

namespace lmb::bench {

namespace {

struct BenchPoseArgs {
  std::string model;
  std::string map;
  int seeds = 5;
  int iterations = 100;
  std::vector<int> budgets = {50, 500};
  int plain_iterations = 500;
  double max_error_px = 8.0;
  double min_margin = 0.0;
  int max_frames = 0;
  std::string json;
};

struct Frame {
  Camera camera;
  Rigid3d truth;
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  std::vector<double> margins;
};

// One setting of the estimator and what it measured.
struct Setting {
  std::string name;
  int iterations = 0;
  bool progressive = true;         // PROSAC in the margin order; false = uniform samples
  bool local_optimization = true;  // PoseEstimatorOptions::refine
  std::vector<int> correct;        // per seed
  std::vector<int> localized;      // per seed
  double cpu_ms = 0.0;             // summed over seeds and frames
  // The loop's statistics summed over seeds and frames (infer/ransac.h's RansacStats).
  double samples = 0.0, models = 0.0, refinements = 0.0;
};

bool is_correct(const Rigid3d& estimate, const Rigid3d& truth) {
  return position_error(estimate, truth) <= 0.20 && rotation_error_deg(estimate, truth) <= 5.0;
}

// The correspondences of every query frame, once (the pose of this pass is not used).
std::vector<Frame> classify_frames(const BenchPoseArgs& a, const std::shared_ptr<const Model>& model,
                                   const LandmarkMap& map) {
  LocalizerOptions lo;
  lo.classifier.min_margin = a.min_margin;
  lo.pose.max_iterations = 1;
  const Localizer localizer(model, lo);
  std::vector<Frame> frames;
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const MapFrame& mf = map.frames[f];
    if (!mf.is_query) continue;
    if (a.max_frames > 0 && static_cast<int>(frames.size()) >= a.max_frames) break;
    const std::vector<Keypoint> keypoints(map.keypoints.begin() + mf.first_keypoint,
                                          map.keypoints.begin() + mf.first_keypoint + mf.num_keypoints);
    const LocalizeResult r =
        localizer.localize(map.cameras[mf.camera], keypoints, map.descriptor(mf.first_keypoint), mf.gravity_in_cam);
    Frame fr;
    fr.camera = map.cameras[mf.camera];
    fr.truth = mf.cam_from_world;
    for (size_t i = 0; i < r.correspondence_keypoint.size(); ++i) {
      const Keypoint& kp = keypoints[r.correspondence_keypoint[i]];
      const ClassMatch& m = r.matches.matches[r.correspondence_match[i]];
      fr.pixels.emplace_back(kp.x, kp.y);
      fr.points.push_back(model->class_position(m.cls));
      fr.margins.push_back(m.score - m.background_score);
    }
    frames.push_back(std::move(fr));
  }
  return frames;
}

// The settings in table order: plain RANSAC first (the time reference), then the estimator at
// --iterations and at each other budget of --budgets (once each), then its uniform-sampling
// ablation.
std::vector<Setting> make_settings(const BenchPoseArgs& a) {
  auto setting = [&](std::string name, int iterations, bool progressive, bool local_optimization) {
    Setting s;
    s.name = std::move(name);
    s.iterations = iterations;
    s.progressive = progressive;
    s.local_optimization = local_optimization;
    s.correct.assign(a.seeds, 0);
    s.localized.assign(a.seeds, 0);
    return s;
  };
  std::vector<Setting> settings;
  settings.push_back(setting("plain_ransac", a.plain_iterations, false, false));
  settings.push_back(setting("lo_ransac_prosac", a.iterations, true, true));
  std::vector<int> budgets = {a.iterations};
  for (const int budget : a.budgets) {
    if (std::find(budgets.begin(), budgets.end(), budget) != budgets.end()) continue;  // the same row
    budgets.push_back(budget);
    settings.push_back(setting("lo_ransac_prosac", budget, true, true));
  }
  settings.push_back(setting("lo_ransac_uniform", a.iterations, false, true));
  return settings;
}

// Every setting on every frame at every seed.
std::vector<Setting> run_settings(const BenchPoseArgs& a, const std::vector<Frame>& frames) {
  std::vector<Setting> settings = make_settings(a);
  spdlog::info("bench pose: {} query frames, {} seeds, {} settings", frames.size(), a.seeds, settings.size());
  for (int seed = 0; seed < a.seeds; ++seed) {
    for (const Frame& fr : frames) {
      // The settings alternate frame by frame, so that the machine's load falls on all alike.
      for (Setting& s : settings) {
        PoseEstimatorOptions o;
        o.max_iterations = s.iterations;
        o.max_reprojection_error_px = a.max_error_px;
        o.seed = static_cast<uint64_t>(seed + 1);
        o.progressive_sampling = s.progressive;
        o.refine = s.local_optimization;
        const double t0 = thread_cpu_ms();
        const PoseResult r = estimate_absolute_pose(fr.camera, fr.pixels, fr.points, o, fr.margins);
        s.cpu_ms += thread_cpu_ms() - t0;
        s.localized[seed] += r.success;
        s.correct[seed] += r.success && is_correct(r.cam_from_world, fr.truth);
        s.samples += r.stats.iterations;
        s.models += r.stats.models;
        // Without local optimisation the loop still counts its (empty) refinement calls.
        if (s.local_optimization) s.refinements += r.stats.refinements;
      }
    }
  }
  return settings;
}

// Prints the table and returns the JSON report.
nlohmann::json report(const BenchPoseArgs& a, const std::vector<Frame>& frames, const std::vector<Setting>& settings) {
  const double runs = static_cast<double>(frames.size()) * a.seeds;
  const double plain_ms = settings.front().cpu_ms / runs;
  nlohmann::json j;
  j["model"] = a.model;
  j["map"] = a.map;
  j["frames"] = frames.size();
  j["seeds"] = a.seeds;
  j["settings"] = {
      {"iterations", a.iterations},     {"budgets", a.budgets},       {"plain_iterations", a.plain_iterations},
      {"max_error_px", a.max_error_px}, {"min_margin", a.min_margin}, {"machine", machine_info().summary()}};
  j["solvers"] = nlohmann::json::array();
  std::printf(
      "\nPose estimator settings on %zu query frames x %d seeds (%s); recall = within 20 cm / 5 deg, of all "
      "frames; speed-up against plain_ransac\n",
      frames.size(), a.seeds, machine_info().summary().c_str());
  std::printf("%-20s %10s %8s %8s %8s %12s %9s %8s %8s %8s\n", "solver", "iterations", "recall", "min", "max",
              "cpu ms/frame", "speed-up", "samples", "models", "LO");
  for (const Setting& s : settings) {
    double sum = 0, lo_r = 1, hi_r = 0;
    std::vector<double> recall;
    for (int seed = 0; seed < a.seeds; ++seed) {
      const double r = static_cast<double>(s.correct[seed]) / static_cast<double>(frames.size());
      recall.push_back(r);
      sum += r;
      lo_r = std::min(lo_r, r);
      hi_r = std::max(hi_r, r);
    }
    const double ms = s.cpu_ms / runs;
    std::printf("%-20s %10d %8.4f %8.4f %8.4f %12.3f %8.2fx %8.1f %8.1f %8.2f\n", s.name.c_str(), s.iterations,
                sum / a.seeds, lo_r, hi_r, ms, plain_ms / ms, s.samples / runs, s.models / runs, s.refinements / runs);
    j["solvers"].push_back({{"name", s.name},
                            {"iterations", s.iterations},
                            {"sampling", s.progressive ? "prosac" : "uniform"},
                            {"local_optimization", s.local_optimization},
                            {"recall_per_seed", recall},
                            {"correct_per_seed", s.correct},
                            {"localized_per_seed", s.localized},
                            {"recall_mean", sum / a.seeds},
                            {"recall_min", lo_r},
                            {"recall_max", hi_r},
                            {"cpu_ms_per_frame", ms},
                            {"speedup_vs_plain_ransac", plain_ms / ms},
                            {"samples_per_frame", s.samples / runs},
                            {"models_per_frame", s.models / runs},
                            {"refinements_per_frame", s.refinements / runs}});
  }
  return j;
}

void run_bench_pose(const BenchPoseArgs& a) {
  check_outputs_not_inputs({{a.json, "--json"}}, {{a.model, "--model"}, {a.map, "--map"}});
  LMB_CHECK(a.seeds >= 1 && a.seeds <= 1000, "--seeds " << a.seeds << " must be in 1..1000");
  LMB_CHECK(a.iterations >= 1, "--iterations " << a.iterations << " must be >= 1");
  LMB_CHECK(a.plain_iterations >= 1, "--plain-iterations " << a.plain_iterations << " must be >= 1");
  for (const int budget : a.budgets) LMB_CHECK(budget >= 1, "--budgets: " << budget << " must be >= 1");
  if (!a.json.empty()) check_writable_file(a.json, "--json");
  const std::shared_ptr<const Model> model = Model::load(a.model);
  const LandmarkMap map = read_map_h5(a.map);
  LMB_CHECK(map.descriptor_bytes == model->descriptor_bytes(), a.map << ": " << map.descriptor_bytes
                                                                     << "-byte descriptors, the model expects "
                                                                     << model->descriptor_bytes());
  const std::vector<Frame> frames = classify_frames(a, model, map);
  LMB_CHECK(!frames.empty(), a.map << ": no query frames");
  const nlohmann::json j = report(a, frames, run_settings(a, frames));
  if (!a.json.empty()) write_file_atomically(a.json, j.dump(1) + "\n");
}

}  // namespace

void add_pose_bench(CLI::App& app) {
  auto args = std::make_shared<BenchPoseArgs>();
  auto* cmd = app.add_subcommand(
      "pose",
      "The pose estimator on the same correspondences: LO-RANSAC with PROSAC at several sample budgets, with "
      "uniform samples, and as plain RANSAC");
  cmd->add_option("--model", args->model, "Inference model (model.lbm)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--map", args->map, "Map with query frames and their true poses (map.h5)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--seeds", args->seeds, "RANSAC seeds 1..N")->capture_default_str();
  cmd->add_option(
         "--iterations", args->iterations,
         "Samples of LO-RANSAC with PROSAC (the settings localization uses) and of the same with uniform samples")
      ->capture_default_str();
  cmd->add_option(
         "--budgets", args->budgets,
         "Other sample budgets of LO-RANSAC with PROSAC, comma-separated (one equal to --iterations adds no row)")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--plain-iterations", args->plain_iterations,
                  "Samples of plain RANSAC: uniform samples, no local optimisation")
      ->capture_default_str();
  cmd->add_option("--max-error", args->max_error_px, "Inlier threshold, pixels")->capture_default_str();
  cmd->add_option("--min-margin", args->min_margin, "Background rejection of the matches")->capture_default_str();
  cmd->add_option("--max-frames", args->max_frames, "At most this many query frames (0 = all)")->capture_default_str();
  cmd->add_option("--json", args->json, "Also write the figures as JSON");
  cmd->callback([args] { run_bench_pose(*args); });
}

}  // namespace lmb::bench
