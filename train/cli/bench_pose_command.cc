// `lboost bench pose`: the pose solvers on the same correspondences, in one run. Each query frame
// of a map with ground truth is classified once by the model (the Localizer's correspondences and
// their margins over the background); then, for each RANSAC seed, frame by frame, every solver
// estimates the pose from them:
//   ransac_opengv      the estimator before issue 18 (train/cli/legacy_pose_estimator.h: OpenGV's
//                      RANSAC, uniform 4-point KNEIP samples, --baseline-iterations), refined
//   lo_ransac_prosac   infer's estimate_absolute_pose: PROSAC in the margin order + LO
//                      (--iterations)
//   lo_ransac_uniform  the same with uniform sampling (ablation)
// Reported per solver: pose recall (geometric success within 20 cm / 5 deg, over the frames with
// ground truth) per seed with mean and range, and thread CPU milliseconds of the pose step per
// frame, with the ratio against ransac_opengv measured in the same run; for the LO-RANSAC solvers
// also the samples (P3P calls), models scored and local optimisations per frame.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
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
#include "train/cli/commands.h"
#include "train/cli/legacy_pose_estimator.h"
#include "train/eval/timing.h"

namespace lmb::cli {

namespace {

struct BenchPoseArgs {
  std::string model;
  std::string map;
  int seeds = 5;
  int iterations = 100;
  int baseline_iterations = 500;
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

struct Solver {
  std::string name;
  std::vector<int> correct;    // per seed
  std::vector<int> localized;  // per seed
  double cpu_ms = 0.0;         // summed over seeds and frames
  // LO-RANSAC's statistics summed over seeds and frames (infer/ransac.h's RansacStats).
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

// Every solver on every frame at every seed.
std::vector<Solver> run_solvers(const BenchPoseArgs& a, const std::vector<Frame>& frames) {
  spdlog::info("bench pose: {} query frames, {} seeds; ransac_opengv {} iterations, lo_ransac {} iterations",
               frames.size(), a.seeds, a.baseline_iterations, a.iterations);

  std::vector<Solver> solvers(3);
  solvers[0].name = "ransac_opengv";
  solvers[1].name = "lo_ransac_prosac";
  solvers[2].name = "lo_ransac_uniform";
  for (Solver& s : solvers) {
    s.correct.assign(a.seeds, 0);
    s.localized.assign(a.seeds, 0);
  }
  for (int seed = 0; seed < a.seeds; ++seed) {
    for (const Frame& fr : frames) {
      // The solvers alternate frame by frame, so that the machine's load falls on all alike.
      {
        legacy::LegacyPoseOptions o;
        o.max_iterations = a.baseline_iterations;
        o.max_reprojection_error_px = a.max_error_px;
        o.seed = static_cast<uint64_t>(seed + 1);
        const double t0 = thread_cpu_ms();
        const legacy::LegacyPoseResult r = legacy::estimate_absolute_pose(fr.camera, fr.pixels, fr.points, o);
        solvers[0].cpu_ms += thread_cpu_ms() - t0;
        solvers[0].localized[seed] += r.success;
        solvers[0].correct[seed] += r.success && is_correct(r.cam_from_world, fr.truth);
      }
      for (int k = 1; k <= 2; ++k) {
        PoseEstimatorOptions o;
        o.max_iterations = a.iterations;
        o.max_reprojection_error_px = a.max_error_px;
        o.seed = static_cast<uint64_t>(seed + 1);
        o.progressive_sampling = k == 1;
        const double t0 = thread_cpu_ms();
        const PoseResult r = estimate_absolute_pose(fr.camera, fr.pixels, fr.points, o, fr.margins);
        solvers[k].cpu_ms += thread_cpu_ms() - t0;
        solvers[k].localized[seed] += r.success;
        solvers[k].correct[seed] += r.success && is_correct(r.cam_from_world, fr.truth);
        solvers[k].samples += r.stats.iterations;
        solvers[k].models += r.stats.models;
        solvers[k].refinements += r.stats.refinements;
      }
    }
  }
  return solvers;
}

// Prints the table and returns the JSON report.
nlohmann::json report(const BenchPoseArgs& a, const std::vector<Frame>& frames, const std::vector<Solver>& solvers) {
  const double runs = static_cast<double>(frames.size()) * a.seeds;
  const double baseline_ms = solvers[0].cpu_ms / runs;
  nlohmann::json j;
  j["model"] = a.model;
  j["map"] = a.map;
  j["frames"] = frames.size();
  j["seeds"] = a.seeds;
  j["settings"] = {{"iterations", a.iterations},
                   {"baseline_iterations", a.baseline_iterations},
                   {"max_error_px", a.max_error_px},
                   {"min_margin", a.min_margin},
                   {"machine", machine_info().summary()}};
  std::printf("\nPose solvers on %zu query frames x %d seeds (%s); recall = within 20 cm / 5 deg, of all frames\n",
              frames.size(), a.seeds, machine_info().summary().c_str());
  std::printf("%-20s %10s %8s %8s %8s %12s %9s %8s %8s %8s\n", "solver", "iterations", "recall", "min", "max",
              "cpu ms/frame", "speed-up", "samples", "models", "LO");
  for (size_t k = 0; k < solvers.size(); ++k) {
    const Solver& s = solvers[k];
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
    const int iterations = k == 0 ? a.baseline_iterations : a.iterations;
    std::printf("%-20s %10d %8.4f %8.4f %8.4f %12.3f %8.2fx", s.name.c_str(), iterations, sum / a.seeds, lo_r, hi_r, ms,
                baseline_ms / ms);
    if (k == 0) {
      std::printf(" %8s %8s %8s\n", "-", "-", "-");
    } else {
      std::printf(" %8.1f %8.1f %8.2f\n", s.samples / runs, s.models / runs, s.refinements / runs);
    }
    j["solvers"][s.name] = {{"iterations", iterations},
                            {"recall_per_seed", recall},
                            {"correct_per_seed", s.correct},
                            {"localized_per_seed", s.localized},
                            {"recall_mean", sum / a.seeds},
                            {"recall_min", lo_r},
                            {"recall_max", hi_r},
                            {"cpu_ms_per_frame", ms},
                            {"speedup_vs_ransac_opengv", baseline_ms / ms}};
    if (k > 0) {
      j["solvers"][s.name]["samples_per_frame"] = s.samples / runs;
      j["solvers"][s.name]["models_per_frame"] = s.models / runs;
      j["solvers"][s.name]["refinements_per_frame"] = s.refinements / runs;
    }
  }
  return j;
}

void run_bench_pose(const BenchPoseArgs& a) {
  LMB_CHECK(a.seeds >= 1 && a.seeds <= 1000, "bench pose: --seeds " << a.seeds << " must be in 1..1000");
  LMB_CHECK(a.iterations >= 1 && a.baseline_iterations >= 1, "bench pose: iterations must be >= 1");
  if (!a.json.empty()) check_writable_file(a.json, "--json");
  const std::shared_ptr<const Model> model = Model::load(a.model);
  const LandmarkMap map = read_map_h5(a.map);
  LMB_CHECK(map.descriptor_bytes == model->descriptor_bytes(), a.map << ": " << map.descriptor_bytes
                                                                     << "-byte descriptors, the model expects "
                                                                     << model->descriptor_bytes());
  const std::vector<Frame> frames = classify_frames(a, model, map);
  LMB_CHECK(!frames.empty(), a.map << ": no query frames");
  const nlohmann::json j = report(a, frames, run_solvers(a, frames));
  if (!a.json.empty()) write_file_atomically(a.json, j.dump(1) + "\n");
}

}  // namespace

void add_bench_pose_command(CLI::App& app) {
  CLI::App* bench = app.get_subcommand("bench");
  auto args = std::make_shared<BenchPoseArgs>();
  auto* cmd = bench->add_subcommand(
      "pose", "Pose solvers on the same correspondences: OpenGV RANSAC (before issue 18) vs LO-RANSAC with PROSAC");
  cmd->add_option("--model", args->model, "Inference model (model.lbm)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--map", args->map, "Map with query frames (map.h5)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--seeds", args->seeds, "RANSAC seeds 1..N")->capture_default_str();
  cmd->add_option("--iterations", args->iterations, "LO-RANSAC samples")->capture_default_str();
  cmd->add_option("--baseline-iterations", args->baseline_iterations, "OpenGV RANSAC iterations")
      ->capture_default_str();
  cmd->add_option("--max-error", args->max_error_px, "Inlier threshold, pixels")->capture_default_str();
  cmd->add_option("--min-margin", args->min_margin, "Background rejection of the matches")->capture_default_str();
  cmd->add_option("--max-frames", args->max_frames, "At most this many query frames (0 = all)")->capture_default_str();
  cmd->add_option("--json", args->json, "Also write the figures as JSON");
  cmd->callback([args] { run_bench_pose(*args); });
}

}  // namespace lmb::cli
