// `lboost eval`: LandmarkBoost and the descriptor-matching baselines on the same query frames of a
// map, as in the paper's experimental evaluation. Writes report.json (DESIGN.md "The results
// report"; train/eval/report.h) and prints the results table.
//
//   lboost eval --model model.lbm --map map.h5 --report report.json [--run RUN_DIR]
//               [--keypoint-ranks ranks.json] [--methods a,b,...] [--top-k 20] ...
//
// Query frames are the map's frames marked is_query; a query keypoint's true landmark is its
// joint-mapping landmark when that landmark is one of the model's classes (the K landmarks the
// classifier was trained on), otherwise the keypoint counts as background for the retrieval
// metrics. The baselines search the same classes' observations in the map's non-query frames (the
// observations training used). Methods:
//   landmarkboost          the inference library's Localizer, dense scoring of all classes
//   landmarkboost_invfile  the same with the inverted file (the keypoint word's classes only)
//   bruteforce_hamming     exact Hamming k-NN over every training observation (OpenCV BFMatcher,
//                          or --hamming-backend popcount)
//   projected_kdtree       exact k-NN of PCA-projected 16-d descriptors
// Each method ranks at most --top-k distinct landmarks per keypoint (the baselines from their
// 4 * top-k nearest observations). Every method's best match per keypoint goes to the same PnP +
// RANSAC (infer/pose_estimator.h: --ransac-iterations, one inlier threshold --max-error, the same
// seed); no voting or clustering. With --max-correspondences N only the N most confident matches
// are used (LandmarkBoost: margin over the background; baselines: smallest distance). Times are
// single-thread (one frame at a time, OpenCV limited to one thread): match = descriptor
// quantization + context + scoring, or the k-NN search; total = match + pose.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/file_container.h"
#include "common/io/map_h5.h"
#include "common/landmark_map.h"
#include "common/machine_info.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "infer/pose_estimator.h"
#include "train/cli/commands.h"
#include "train/cli/timing.h"
#include "train/eval/baselines.h"
#include "train/eval/metrics.h"
#include "train/eval/report.h"

namespace lmb::cli {

namespace {

const std::vector<std::string> kAllMethods = {"landmarkboost", "landmarkboost_invfile", "bruteforce_hamming",
                                              "projected_kdtree"};

struct EvalArgs {
  std::string model;
  std::string map;
  std::string report;
  std::string run;
  std::string keypoint_ranks;
  std::vector<std::string> methods = kAllMethods;
  int top_k = 20;
  double min_margin = 0.0;
  int max_correspondences = 0;
  PoseEstimatorOptions pose;
  std::string hamming_backend = "opencv";
  int pca_dims = 16;
};

// One query frame's inputs.
struct QueryFrame {
  frame_t frame = kInvalidFrameId;
  std::vector<Keypoint> keypoints;
  std::vector<landmark_t> truth;  // per keypoint: a model class's landmark, or kInvalidLandmarkId
};

// What one method returns for one frame.
struct FrameRun {
  std::vector<std::vector<RankedCandidate>> candidates;  // per keypoint, best first
  FrameOutcome outcome;
  double ranking_cpu_ms = 0.0;  // LandmarkBoost: thread CPU time of the untimed ranking pass
};

// The model and the map must describe the same landmarks: every class's landmark exists in the
// map at the same position. Returns the landmark -> class flag.
std::vector<char> check_model_against_map(const Model& model, const LandmarkMap& map, const EvalArgs& a) {
  LMB_CHECK(map.descriptor_bytes == model.descriptor_bytes(),
            a.map << ": " << map.descriptor_bytes << "-byte descriptors, but " << a.model << " expects "
                  << model.descriptor_bytes() << " (a model of another detector?)");
  std::vector<char> is_class(map.landmarks.size(), 0);
  for (int32_t c = 0; c < model.num_classes(); ++c) {
    const landmark_t l = model.class_landmark(c);
    LMB_CHECK(l >= 0 && l < static_cast<landmark_t>(map.landmarks.size()),
              a.model << ": class " << c << " is landmark " << l << ", but " << a.map << " has "
                      << map.landmarks.size() << " landmarks (the model was trained on another map)");
    const double d = (map.landmarks[l].position - model.class_position(c)).norm();
    LMB_CHECK(d <= 1e-6 * std::max(1.0, map.landmarks[l].position.norm()),
              a.model << ": class " << c << " (landmark " << l << ") lies " << d << " m from that landmark in "
                      << a.map << " (the model was trained on another map)");
    is_class[l] = 1;
  }
  return is_class;
}

std::vector<QueryFrame> query_frames(const LandmarkMap& map, const std::vector<char>& is_class, const EvalArgs& a) {
  std::vector<QueryFrame> out;
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const MapFrame& frame = map.frames[f];
    if (!frame.is_query) continue;
    QueryFrame q;
    q.frame = f;
    q.keypoints.assign(map.keypoints.begin() + frame.first_keypoint,
                       map.keypoints.begin() + frame.first_keypoint + frame.num_keypoints);
    for (int32_t k = 0; k < frame.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[frame.first_keypoint + k];
      q.truth.push_back(l != kInvalidLandmarkId && is_class[l] ? l : kInvalidLandmarkId);
    }
    out.push_back(std::move(q));
  }
  LMB_CHECK(!out.empty(), a.map << ": no query frames (frames with is_query set; map the query images jointly, "
                                   "see `lboost map --help`)");
  return out;
}

// Each keypoint's best candidate, at most max_correspondences of them (largest score first, ties in
// keypoint order), back in keypoint order: the correspondences a baseline gives to the pose
// estimator. The same rule as the Localizer's with pose_top_k = 1 (there the score is the margin).
std::vector<std::pair<int32_t, landmark_t>> best_matches(const std::vector<std::vector<RankedCandidate>>& cand,
                                                         int max_correspondences) {
  std::vector<int32_t> keypoints;
  for (size_t k = 0; k < cand.size(); ++k) {
    if (!cand[k].empty()) keypoints.push_back(static_cast<int32_t>(k));
  }
  if (max_correspondences > 0 && keypoints.size() > static_cast<size_t>(max_correspondences)) {
    std::stable_sort(keypoints.begin(), keypoints.end(),
                     [&](int32_t x, int32_t y) { return cand[x][0].score > cand[y][0].score; });
    keypoints.resize(static_cast<size_t>(max_correspondences));
    std::sort(keypoints.begin(), keypoints.end());
  }
  std::vector<std::pair<int32_t, landmark_t>> out;
  for (int32_t k : keypoints) out.emplace_back(k, cand[k][0].landmark);
  return out;
}

// A descriptor-matching baseline on one frame: its k-NN search (timed), then the shared pose step.
template <typename Search>
FrameRun run_baseline(const LandmarkMap& map, const QueryFrame& q, const EvalArgs& a, const Search& search) {
  const MapFrame& frame = map.frames[q.frame];
  FrameRun r;
  const Clock::time_point t0 = Clock::now();
  r.candidates = search(map.descriptor(frame.first_keypoint), frame.num_keypoints);
  for (auto& c : r.candidates) {
    if (c.size() > static_cast<size_t>(a.top_k)) c.resize(static_cast<size_t>(a.top_k));
  }
  r.outcome.match_ms = ms_since(t0);
  const auto matches = best_matches(r.candidates, a.max_correspondences);
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  for (const auto& [k, l] : matches) {
    pixels.emplace_back(q.keypoints[k].x, q.keypoints[k].y);
    points.push_back(map.landmarks[l].position);
  }
  const PoseResult pose = estimate_absolute_pose(map.cameras[frame.camera], pixels, points, a.pose);
  r.outcome.total_ms = ms_since(t0);
  r.outcome.localized = pose.success;
  r.outcome.cam_from_world = pose.cam_from_world;
  r.outcome.num_correspondences = static_cast<int>(pixels.size());
  r.outcome.num_inliers = pose.num_inliers;
  return r;
}

// LandmarkBoost on one frame. The ranking (P@1, MRR, miss rate) comes from `ranker`, which keeps
// every keypoint's ranked landmarks without background rejection, each with its margin over the
// background as the confidence (the same order as the scores within a keypoint, and comparable
// across keypoints); the pose and the times come from `localizer`, the configured pipeline
// (background rejection at --min-margin), as an app would run it.
FrameRun run_landmarkboost(const Localizer& ranker, const Localizer& localizer, const LandmarkMap& map,
                           const QueryFrame& q) {
  const MapFrame& frame = map.frames[q.frame];
  const double c0 = thread_cpu_ms();
  const LocalizeResult ranked = ranker.localize(map.cameras[frame.camera], q.keypoints,
                                                map.descriptor(frame.first_keypoint), frame.gravity_in_cam);
  FrameRun r;
  r.ranking_cpu_ms = thread_cpu_ms() - c0;
  r.candidates.resize(q.keypoints.size());
  for (int32_t k = 0; k < ranked.matches.num_keypoints(); ++k) {
    for (int32_t j = 0; j < ranked.matches.count(k); ++j) {
      const ClassMatch& m = ranked.matches.of(k)[j];
      r.candidates[k].push_back(RankedCandidate{m.landmark, m.score - m.background_score});
    }
  }
  const LocalizeResult lr = localizer.localize(map.cameras[frame.camera], q.keypoints,
                                               map.descriptor(frame.first_keypoint), frame.gravity_in_cam);
  r.outcome.localized = lr.pose.success;
  r.outcome.cam_from_world = lr.pose.cam_from_world;
  r.outcome.num_correspondences = static_cast<int>(lr.correspondence_keypoint.size());
  r.outcome.num_inliers = lr.pose.num_inliers;
  r.outcome.match_ms = lr.timings.words_ms + lr.timings.embedding_ms + lr.timings.classification_ms;
  r.outcome.total_ms = lr.timings.total_ms;
  return r;
}

struct MethodRun {
  MethodResult result;
  double build_seconds = 0.0;                 // index construction (baselines)
  std::vector<std::vector<int32_t>> ranks;    // per frame, per keypoint: 1-based rank of the truth, 0 absent
  double cpu_ms_per_frame = 0.0;              // thread CPU time of matching + pose, mean over frames
};

MethodRun evaluate_method(const std::string& name, const std::shared_ptr<const Model>& model,
                          const LandmarkMap& map, const std::vector<QueryFrame>& queries, const EvalArgs& a) {
  MethodRun run;
  run.result.name = name;
  const int knn_k = 4 * a.top_k;
  std::vector<FrameRun> frames;
  const Clock::time_point t_build = Clock::now();
  if (name == "landmarkboost" || name == "landmarkboost_invfile") {
    LocalizerOptions options;
    options.classifier.top_k = a.top_k;
    options.classifier.use_inverted_file = name == "landmarkboost_invfile";
    options.classifier.min_margin = a.min_margin;
    options.pose_top_k = 1;
    options.max_correspondences = a.max_correspondences;
    options.pose = a.pose;
    const Localizer localizer(model, options);
    LocalizerOptions ranking = options;
    ranking.classifier.min_margin = -std::numeric_limits<double>::infinity();
    ranking.pose.max_iterations = 1;  // its pose is not used
    const Localizer ranker(model, ranking);
    for (const QueryFrame& q : queries) {
      // Only the configured localizer's run is timed (thread CPU time is read around both here,
      // so the ranking pass is subtracted).
      const double c0 = thread_cpu_ms();
      FrameRun fr = run_landmarkboost(ranker, localizer, map, q);
      run.cpu_ms_per_frame += thread_cpu_ms() - c0 - fr.ranking_cpu_ms;
      frames.push_back(std::move(fr));
    }
  } else {
    std::vector<landmark_t> classes;
    for (int32_t c = 0; c < model->num_classes(); ++c) classes.push_back(model->class_landmark(c));
    TrainingObservations obs = collect_training_observations(map, classes);
    LMB_CHECK(obs.size() > 0, a.map << ": the model's " << classes.size()
                                    << " landmarks have no observation in non-query frames");
    if (name == "bruteforce_hamming") {
      const BruteforceHamming index(std::move(obs), a.hamming_backend == "popcount"
                                                        ? BruteforceHamming::Backend::kPopcount
                                                        : BruteforceHamming::Backend::kOpenCv);
      run.build_seconds = ms_since(t_build) / 1000.0;
      for (const QueryFrame& q : queries) {
        const double c0 = thread_cpu_ms();
        frames.push_back(run_baseline(map, q, a, [&](const uint8_t* d, int32_t n) {
          return index.query_batch(d, n, knn_k);
        }));
        run.cpu_ms_per_frame += thread_cpu_ms() - c0;
      }
    } else {
      ProjectedKdTreeOptions options;
      options.dims = a.pca_dims;
      const ProjectedKdTree index(std::move(obs), options);
      run.build_seconds = ms_since(t_build) / 1000.0;
      for (const QueryFrame& q : queries) {
        const double c0 = thread_cpu_ms();
        frames.push_back(run_baseline(map, q, a, [&](const uint8_t* d, int32_t n) {
          std::vector<std::vector<RankedCandidate>> out(static_cast<size_t>(n));
          for (int32_t k = 0; k < n; ++k) out[k] = index.query(d + static_cast<int64_t>(k) * map.descriptor_bytes, knn_k);
          return out;
        }));
        run.cpu_ms_per_frame += thread_cpu_ms() - c0;
      }
    }
  }
  std::vector<KeypointRanking> rankings;
  for (size_t i = 0; i < queries.size(); ++i) {
    const QueryFrame& q = queries[i];
    FrameRun& fr = frames[i];
    fr.outcome.true_cam_from_world = map.frames[q.frame].cam_from_world;
    fr.outcome.confidence = fr.outcome.num_inliers;
    run.result.frames.push_back(fr.outcome);
    std::vector<int32_t> ranks;
    for (size_t k = 0; k < q.keypoints.size(); ++k) {
      int32_t rank = 0;
      for (size_t j = 0; j < fr.candidates[k].size() && rank == 0; ++j) {
        if (fr.candidates[k][j].landmark == q.truth[k]) rank = static_cast<int32_t>(j) + 1;
      }
      ranks.push_back(rank);
      rankings.push_back(KeypointRanking{std::move(fr.candidates[k]), q.truth[k]});
    }
    run.ranks.push_back(std::move(ranks));
  }
  run.cpu_ms_per_frame /= static_cast<double>(queries.size());
  run.result.retrieval = evaluate_retrieval(rankings);
  run.result.pose = evaluate_poses(run.result.frames);
  return run;
}

void run_eval(const EvalArgs& a) {
  LMB_CHECK(a.top_k >= 1 && a.top_k <= 10000, "eval: --top-k " << a.top_k << " must be in 1..10000");
  LMB_CHECK(a.max_correspondences >= 0, "eval: --max-correspondences " << a.max_correspondences << " must be >= 0");
  LMB_CHECK(a.hamming_backend == "opencv" || a.hamming_backend == "popcount",
            "eval: --hamming-backend '" << a.hamming_backend << "' must be opencv or popcount");
  LMB_CHECK(!a.methods.empty(), "eval: --methods is empty");
  std::set<std::string> seen;
  for (const std::string& m : a.methods) {
    LMB_CHECK(std::find(kAllMethods.begin(), kAllMethods.end(), m) != kAllMethods.end(),
              "eval: --methods: unknown method '" << m << "' (known: landmarkboost, landmarkboost_invfile, "
                                                     "bruteforce_hamming, projected_kdtree)");
    LMB_CHECK(seen.insert(m).second, "eval: --methods: '" << m << "' given twice");
  }
  a.pose.check();
  cv::setNumThreads(1);

  const std::shared_ptr<const Model> model = Model::load(a.model);
  const LandmarkMap map = read_map_h5(a.map);
  const std::vector<char> is_class = check_model_against_map(*model, map, a);
  const std::vector<QueryFrame> queries = query_frames(map, is_class, a);

  DatasetCounts counts;
  int64_t with_class_truth = 0;
  for (const MapFrame& f : map.frames) (f.is_query ? counts.query_frames : counts.map_frames) += 1;
  counts.landmarks = static_cast<int64_t>(map.landmarks.size());
  for (const QueryFrame& q : queries) {
    const MapFrame& f = map.frames[q.frame];
    counts.query_keypoints += f.num_keypoints;
    for (int32_t k = 0; k < f.num_keypoints; ++k) {
      counts.query_keypoints_with_truth += map.keypoint_landmark[f.first_keypoint + k] != kInvalidLandmarkId;
    }
    for (landmark_t t : q.truth) with_class_truth += t != kInvalidLandmarkId;
  }
  LMB_CHECK(with_class_truth > 0, a.map << ": none of the " << counts.query_keypoints
                                        << " query keypoints observes one of the model's " << model->num_classes()
                                        << " landmarks (were the query frames mapped jointly with the map?)");
  std::string method_list;
  for (const std::string& m : a.methods) method_list += (method_list.empty() ? "" : ", ") + m;
  spdlog::info("eval: {} query frames, {} keypoints ({} with a true landmark, {} of them a model class), "
               "model {} classes, {} stumps; methods: {}",
               counts.query_frames, counts.query_keypoints, counts.query_keypoints_with_truth, with_class_truth,
               model->num_classes(), model->data().stumps.size(), method_list);

  std::vector<MethodResult> results;
  nlohmann::json build = nlohmann::json::object();
  nlohmann::json ranks = nlohmann::json::object();
  nlohmann::json cpu = nlohmann::json::object();
  for (const std::string& name : a.methods) {
    const Clock::time_point t0 = Clock::now();
    MethodRun run = evaluate_method(name, model, map, queries, a);
    spdlog::info("eval: {}: P@1 {:.4f}, MRR {:.4f}, {}/{} frames correct, {:.2f} ms/frame matching ({:.1f} s)",
                 name, run.result.retrieval.precision_at_1, run.result.retrieval.mrr, run.result.pose.num_correct,
                 run.result.pose.num_frames, run.result.pose.mean_match_ms, ms_since(t0) / 1000.0);
    build[name] = run.build_seconds;
    ranks[name] = run.ranks;
    cpu[name] = run.cpu_ms_per_frame;
    results.push_back(std::move(run.result));
  }

  nlohmann::json report = build_report(counts, results);
  for (const auto& [name, ms] : cpu.items()) report["methods"][name]["cpu_ms_per_frame"] = ms;
  report["dataset"]["model_classes"] = model->num_classes();
  report["dataset"]["query_keypoints_with_class_truth"] = with_class_truth;
  report["settings"] = {{"model", a.model},
                        {"map", a.map},
                        {"top_k", a.top_k},
                        {"landmarkboost_min_margin", std::isfinite(a.min_margin) ? nlohmann::json(a.min_margin)
                                                                                  : nlohmann::json(nullptr)},
                        {"max_correspondences", a.max_correspondences},
                        {"ransac_iterations", a.pose.max_iterations},
                        {"inlier_threshold_px", a.pose.max_reprojection_error_px},
                        {"min_inliers", a.pose.min_inliers},
                        {"ransac_seed", a.pose.seed},
                        {"hamming_backend", a.hamming_backend},
                        {"pca_dims", a.pca_dims},
                        {"threads", 1},
                        {"index_build_seconds", build},
                        {"machine", {{"cpu_model", machine_info().cpu_model}, {"logical_cores", machine_info().logical_cores}}}};
  nlohmann::json names = nlohmann::json::array();
  for (const QueryFrame& q : queries) names.push_back(map.frames[q.frame].name);
  report["query_frame_names"] = names;
  if (!a.run.empty()) {
    const std::filesystem::path summary = std::filesystem::path(a.run) / "summary.json";
    std::ifstream in(summary);
    LMB_CHECK(in.good(), "eval: --run " << a.run << ": no summary.json (not a finished `lboost train` run dir)");
    try {
      report["training"] = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception& e) {
      LMB_FAIL(summary.string() << ": not JSON (" << e.what() << ")");
    }
  }
  write_report(a.report, report);
  if (!a.keypoint_ranks.empty()) {
    nlohmann::json side = {{"frames", names},
                           {"truth_rank", ranks},
                           {"note", "per method, per query frame, per keypoint: 1-based rank of the true landmark "
                                    "among the method's candidates, 0 when absent or the keypoint has no true "
                                    "landmark among the model's classes"}};
    write_report(a.keypoint_ranks, side);
  }
  std::printf("\nResults on %lld query frames, %lld query keypoints with a true landmark among the model's %d "
              "classes (%s):\n%s-> %s\n",
              static_cast<long long>(counts.query_frames), static_cast<long long>(with_class_truth),
              model->num_classes(), machine_info().summary().c_str(), format_results_table(report).c_str(),
              a.report.c_str());
  std::string cpu_line;
  for (const auto& [name, ms] : cpu.items()) {
    char cell[128];
    std::snprintf(cell, sizeof(cell), "%s%s %.1f", cpu_line.empty() ? "" : ", ", name.c_str(), ms.get<double>());
    cpu_line += cell;
  }
  std::printf("thread CPU ms per frame (matching + pose; the table's times are wall clock): %s\n", cpu_line.c_str());
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto args = std::make_shared<EvalArgs>();
  auto* cmd = app.add_subcommand(
      "eval", "LandmarkBoost and the descriptor baselines on the map's query frames: report.json + results table");
  cmd->add_option("--model", args->model, "Inference model (model.lbm)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--map", args->map, "The map the model was trained on, with its query frames (map.h5)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--report", args->report, "Output report (JSON, DESIGN.md schema + curves)")->required();
  cmd->add_option("--run", args->run, "Training run dir: its summary.json is copied into the report");
  cmd->add_option("--keypoint-ranks", args->keypoint_ranks,
                  "Side file: every query keypoint's rank of its true landmark, per method");
  cmd->add_option("--methods", args->methods, "Methods to run")->delimiter(',')->capture_default_str();
  cmd->add_option("--top-k", args->top_k, "Ranked landmarks per keypoint (MRR and miss-rate depth)")
      ->capture_default_str();
  cmd->add_option("--min-margin", args->min_margin,
                  "LandmarkBoost: matches fed to RANSAC must beat the background's score by this "
                  "(-inf = no rejection); P@1, MRR and miss rate always rank without rejection")
      ->capture_default_str();
  cmd->add_option("--max-correspondences", args->max_correspondences,
                  "Most confident matches fed to RANSAC, every method (0 = all)")->capture_default_str();
  cmd->add_option("--ransac-iterations", args->pose.max_iterations, "RANSAC iterations")->capture_default_str();
  cmd->add_option("--max-error", args->pose.max_reprojection_error_px, "Inlier threshold, pixels")
      ->capture_default_str();
  cmd->add_option("--min-inliers", args->pose.min_inliers, "Inliers for a pose")->capture_default_str();
  cmd->add_option("--seed", args->pose.seed, "RANSAC seed (the same for every method)")->capture_default_str();
  cmd->add_option("--hamming-backend", args->hamming_backend, "bruteforce_hamming: opencv (BFMatcher) or popcount")
      ->capture_default_str();
  cmd->add_option("--pca-dims", args->pca_dims, "projected_kdtree: PCA dimensions")->capture_default_str();
  cmd->callback([args] { run_eval(*args); });
}

}  // namespace lmb::cli
