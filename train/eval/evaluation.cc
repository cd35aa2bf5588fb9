#include "train/eval/evaluation.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <vector>

#include <spdlog/spdlog.h>
#include <opencv2/core.hpp>

#include "common/error.h"
#include "common/io/map_h5.h"
#include "common/machine_info.h"
#include "train/boost/training_set.h"
#include "train/eval/pose_calibration_fit.h"
#include "train/eval/pose_stage.h"
#include "train/eval/report.h"
#include "train/eval/run_export.h"
#include "train/eval/timing.h"
#include "train/eval/walk_calibration_fit.h"
#include "train/eval/walk_eval.h"

namespace lmb {

namespace {

// The query sessions evaluated (indices into map.sessions, map order): the named ones, or every
// session of kind query.
std::vector<int32_t> selected_sessions(const LandmarkMap& map, const EvalOptions& a) {
  std::string query_names;
  std::vector<int32_t> all_query;
  for (int32_t s = 0; s < static_cast<int32_t>(map.sessions.size()); ++s) {
    if (map.sessions[s].kind != SessionKind::kQuery) continue;
    all_query.push_back(s);
    query_names += (query_names.empty() ? "" : ", ") + map.sessions[s].name;
  }
  if (query_names.empty()) query_names = "none";
  if (a.query_sessions.empty()) {
    LMB_CHECK(!all_query.empty(), a.map << ": no query session (map the query images jointly as a session of kind "
                                           "query, see `lboost map --help`)");
    return all_query;
  }
  std::vector<int32_t> out;
  for (const std::string& name : a.query_sessions) {
    const int32_t s = map.find_session(name);
    LMB_CHECK(s >= 0, "eval: --query-session '" << name << "': " << a.map
                                                << " has no such session (query sessions: " << query_names << ")");
    LMB_CHECK(map.sessions[s].kind != SessionKind::kMap,
              "eval: --query-session '" << name << "': a map session of " << a.map
                                        << " (its frames trained the model; --run ranks its held-out observations)");
    LMB_CHECK(map.sessions[s].kind == SessionKind::kQuery,
              "eval: --query-session '" << name << "': an outside session of " << a.map
                                        << " (recorded where the map has no landmarks: nothing to retrieve)");
    out.push_back(s);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// A frame of the map as a query: its keypoints, and per keypoint `truth(k)` (k: map keypoint).
template <typename Truth>
EvalQuery frame_query(const LandmarkMap& map, frame_t f, Truth truth) {
  EvalQuery q = map_frame_query(map, f);
  const int64_t first = map.frames[f].first_keypoint;
  for (size_t i = 0; i < q.truth.size(); ++i) q.truth[i] = truth(first + static_cast<int64_t>(i));
  return q;
}

// The frames of the selected query sessions, in map order.
std::vector<EvalQuery> query_frames(const LandmarkMap& map, const std::vector<char>& is_class,
                                    const std::vector<int32_t>& sessions, const EvalOptions& a) {
  std::vector<EvalQuery> out;
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    if (!std::binary_search(sessions.begin(), sessions.end(), map.frames[f].session)) continue;
    out.push_back(frame_query(map, f, [&](int64_t k) {
      const landmark_t l = map.keypoint_landmark[k];
      return l != kInvalidLandmarkId && is_class[l] ? l : kInvalidLandmarkId;
    }));
  }
  LMB_CHECK(!out.empty(), a.map << ": no query frames in the query sessions evaluated");
  return out;
}

// The frames of the map's outside sessions (recorded where the map has no landmark), in map order.
std::vector<EvalQuery> outside_frames(const LandmarkMap& map) {
  std::vector<EvalQuery> out;
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const int32_t s = map.frames[f].session;
    if (s < 0 || static_cast<size_t>(s) >= map.sessions.size() || map.sessions[s].kind != SessionKind::kOutside) {
      continue;
    }
    out.push_back(frame_query(map, f, [](int64_t) { return kInvalidLandmarkId; }));
  }
  return out;
}

// The frame's pose at the default budget with each seed; times those of `timed`.
std::vector<FrameOutcome> seed_outcomes(const EvalQuery& q, const PoseInput& input, PoseEstimatorOptions options,
                                        const std::vector<uint64_t>& seeds, const FrameOutcome& timed) {
  std::vector<FrameOutcome> out;
  for (uint64_t seed : seeds) {
    options.seed = seed;
    FrameOutcome o = estimate_frame_pose(q, input, options);
    o.match_ms = timed.match_ms;
    o.total_ms = timed.total_ms;
    out.push_back(o);
  }
  return out;
}

// How many of the outside frames a method reports localized, by the inlier rule and by the
// calibrated rule (every reported pose of an outside frame is wrong).
nlohmann::json evaluate_outside(const EvalMethod& method, const MethodContext& context,
                                const std::vector<EvalQuery>& frames, const CalibrationFit& fit,
                                const std::vector<uint64_t>& seeds, std::vector<std::vector<FrameOutcome>>* by_seed) {
  const EvalOptions& a = *context.options;
  int64_t inlier_rule = 0, calibrated = 0;
  by_seed->clear();
  if (!frames.empty()) {
    const std::unique_ptr<Matcher> matcher = method.make(context);
    by_seed->resize(fit.fitted ? seeds.size() : 0);
    for (const EvalQuery& q : frames) {
      const FrameMatches m = matcher->match(q);
      const PoseInput input = select_correspondences(q, m.accepted, a.max_correspondences);
      const FrameOutcome o = estimate_frame_pose(q, input, a.pose);
      inlier_rule += o.localized;
      calibrated += o.localized && fit.fitted && fit.calibration.probability(o.evidence) >= fit.calibration.threshold;
      if (!fit.fitted) continue;
      const std::vector<FrameOutcome> s = seed_outcomes(q, input, a.pose, seeds, o);
      for (size_t k = 0; k < s.size(); ++k) (*by_seed)[k].push_back(s[k]);
    }
  }
  const double n = static_cast<double>(frames.size());
  nlohmann::json j = {{"frames", frames.size()},
                      {"localized_inlier_rule", inlier_rule},
                      {"share_localized_inlier_rule", frames.empty() ? 0.0 : inlier_rule / n}};
  if (fit.fitted) {
    j["localized_calibrated"] = calibrated;
    j["share_localized_calibrated"] = frames.empty() ? 0.0 : calibrated / n;
  }
  return j;
}

// The map frames holding held-out observations (sorted map keypoints of model classes), as
// queries whose only keypoints with truth are the held-out ones.
std::vector<EvalQuery> held_out_frames(const LandmarkMap& map, const std::vector<int64_t>& held) {
  std::vector<EvalQuery> out;
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const MapFrame& frame = map.frames[f];
    const auto first = std::lower_bound(held.begin(), held.end(), frame.first_keypoint);
    if (first == held.end() || *first >= frame.first_keypoint + frame.num_keypoints) continue;
    out.push_back(frame_query(map, f, [&](int64_t k) {
      return std::binary_search(held.begin(), held.end(), k) ? map.keypoint_landmark[k] : kInvalidLandmarkId;
    }));
  }
  return out;
}

// The dataset's counts; *with_class_truth: query keypoints whose true landmark is a model class.
DatasetCounts count_dataset(const LandmarkMap& map, const std::vector<EvalQuery>& queries, int64_t* with_class_truth) {
  DatasetCounts counts;
  *with_class_truth = 0;
  for (const MapFrame& f : map.frames) counts.map_frames += !f.is_query;
  counts.query_frames = static_cast<int64_t>(queries.size());
  counts.landmarks = static_cast<int64_t>(map.landmarks.size());
  for (const EvalQuery& q : queries) {
    const MapFrame& f = map.frames[q.frame];
    counts.query_keypoints += f.num_keypoints;
    for (int32_t k = 0; k < f.num_keypoints; ++k) {
      counts.query_keypoints_with_truth += map.keypoint_landmark[f.first_keypoint + k] != kInvalidLandmarkId;
    }
    for (landmark_t t : q.truth) *with_class_truth += t != kInvalidLandmarkId;
  }
  return counts;
}

// Adds the frames of `part` to `total` (same budgets and seeds, or `total` empty).
void add_sweep(const PoseSweep& part, PoseSweep& total) {
  if (total.frames_correct.empty()) {
    total = part;
    return;
  }
  const auto add = [](const std::vector<std::vector<int64_t>>& from, std::vector<std::vector<int64_t>>& to) {
    for (size_t b = 0; b < to.size(); ++b) {
      for (size_t s = 0; s < to[b].size(); ++s) to[b][s] += from[b][s];
    }
  };
  add(part.frames_correct, total.frames_correct);
  add(part.frames_localized, total.frames_localized);
  add(part.calibrated_localized, total.calibrated_localized);
  add(part.calibrated_correct, total.calibrated_correct);
  total.num_frames += part.num_frames;
}

struct MethodRun {
  MethodResult result;                      // all evaluated query frames
  std::vector<MethodResult> sessions;       // per evaluated query session (no frames, for the report's summary)
  nlohmann::json parameters;                // the matcher's own parameters
  double build_seconds = 0.0;               // matcher construction (the baselines' index)
  std::vector<std::vector<int32_t>> ranks;  // per frame, per keypoint: 1-based rank of the truth, 0 absent
  double cpu_ms_per_frame = 0.0;            // thread CPU time of matching + pose, mean over frames
  // With a calibration: per seed of the sweep, per query frame, the pose at the default budget (the
  // walks' frames; times those of the timed pose).
  std::vector<std::vector<FrameOutcome>> seed_frames;
};

// 1-based rank of `truth` in `ranking`, 0 when absent.
int32_t rank_of(const std::vector<RankedCandidate>& ranking, landmark_t truth) {
  for (size_t j = 0; j < ranking.size(); ++j) {
    if (ranking[j].landmark == truth) return static_cast<int32_t>(j) + 1;
  }
  return 0;
}

// Each keypoint's accepted match (at most one a keypoint, in keypoint order) and truth.
void add_keypoint_matches(const EvalQuery& q, const std::vector<Correspondence>& accepted,
                          std::vector<KeypointMatch>& out) {
  const size_t first = out.size();
  for (landmark_t t : q.truth) out.push_back(KeypointMatch{kInvalidLandmarkId, t});
  for (const Correspondence& c : accepted) {
    KeypointMatch& m = out[first + static_cast<size_t>(c.keypoint)];
    LMB_CHECK(m.accepted == kInvalidLandmarkId, "eval: a matcher accepted keypoint " << c.keypoint << " twice");
    m.accepted = c.landmark;
  }
}

// The pose metrics at the primary (first) thresholds and the recall at every pair.
void evaluate_pose_stage(const EvalOptions& a, MethodResult& r) {
  r.pose = evaluate_poses(r.frames, a.pose_thresholds.front());
  for (const PoseThresholds& t : a.pose_thresholds) {
    const PoseMetrics p = evaluate_poses(r.frames, t);
    r.recall_at_thresholds.push_back(ThresholdRecall{t, p.num_correct, p.recall});
  }
}

// query_session[i]: the index in the evaluated sessions of queries[i]'s session.
MethodRun evaluate_method(const EvalMethod& method, const MethodContext& context, const std::vector<EvalQuery>& queries,
                          const std::vector<size_t>& query_session, size_t num_sessions, const CalibrationFit& fit) {
  const PoseCalibration* calibration = fit.fitted ? &fit.calibration : nullptr;
  const EvalOptions& a = *context.options;
  MethodRun run;
  run.result.name = method.name;
  const Clock::time_point t_build = Clock::now();
  const std::unique_ptr<Matcher> matcher = method.make(context);
  run.build_seconds = ms_since(t_build) / 1000.0;
  run.parameters = matcher->parameters();
  struct Part {
    std::vector<KeypointRanking> rankings;
    std::vector<KeypointMatch> matches;
    MethodResult result;  // frames and sweep
  };
  std::vector<Part> parts(num_sessions);
  for (Part& p : parts) p.result.sweep = start_pose_sweep(a.sweep, a.pose.seed, fit.fitted);
  for (size_t i = 0; i < queries.size(); ++i) {
    const EvalQuery& q = queries[i];
    Part& part = parts[query_session[i]];
    FrameMatches m = matcher->match(q);
    LMB_CHECK(m.ranking.size() == q.keypoints.size(), "eval: " << method.name << " ranked " << m.ranking.size()
                                                               << " of " << q.keypoints.size() << " keypoints");
    const double c0 = thread_cpu_ms();
    const Clock::time_point t0 = Clock::now();
    const PoseInput input = select_correspondences(q, m.accepted, a.max_correspondences);
    FrameOutcome o = estimate_frame_pose(q, input, a.pose);
    o.match_ms = m.match_ms;
    o.total_ms = m.match_ms + ms_since(t0);
    run.cpu_ms_per_frame += m.cpu_ms + thread_cpu_ms() - c0;
    run.result.frames.push_back(o);
    part.result.frames.push_back(o);
    std::vector<FrameOutcome> by_seed;
    sweep_frame_pose(q, input, a.pose, a.pose_thresholds.front(), part.result.sweep, calibration,
                     fit.fitted ? &by_seed : nullptr);
    run.seed_frames.resize(by_seed.size());
    for (size_t s = 0; s < by_seed.size(); ++s) {
      by_seed[s].match_ms = o.match_ms;
      by_seed[s].total_ms = o.total_ms;
      run.seed_frames[s].push_back(by_seed[s]);
    }
    add_keypoint_matches(q, m.accepted, part.matches);
    std::vector<int32_t> ranks;
    for (size_t k = 0; k < q.keypoints.size(); ++k) {
      ranks.push_back(q.truth[k] == kInvalidLandmarkId ? 0 : rank_of(m.ranking[k], q.truth[k]));
      part.rankings.push_back(KeypointRanking{std::move(m.ranking[k]), q.truth[k]});
    }
    run.ranks.push_back(std::move(ranks));
  }
  run.cpu_ms_per_frame /= static_cast<double>(queries.size());
  std::vector<KeypointRanking> rankings;
  std::vector<KeypointMatch> matches;
  for (Part& p : parts) {
    p.result.name = method.name;
    p.result.retrieval = evaluate_retrieval(p.rankings);
    p.result.matches = evaluate_matches(p.matches);
    evaluate_pose_stage(a, p.result);
    add_sweep(p.result.sweep, run.result.sweep);
    p.result.frames.clear();  // the session summary has no per-frame arrays
    std::move(p.rankings.begin(), p.rankings.end(), std::back_inserter(rankings));
    matches.insert(matches.end(), p.matches.begin(), p.matches.end());
    run.sessions.push_back(std::move(p.result));
  }
  run.result.retrieval = evaluate_retrieval(rankings);
  run.result.matches = evaluate_matches(matches);
  evaluate_pose_stage(a, run.result);
  return run;
}

// The query sessions as walks: per session (in the order of `queries`), per seed, its frames.
std::vector<WalkInput> query_walks(const LandmarkMap& map, const std::vector<EvalQuery>& queries,
                                   const std::vector<std::vector<FrameOutcome>>& seed_frames) {
  std::vector<WalkInput> walks;
  std::vector<int32_t> walk_session;
  for (size_t i = 0; i < queries.size(); ++i) {
    const int32_t session = map.frames[queries[i].frame].session;
    auto it = std::find(walk_session.begin(), walk_session.end(), session);
    if (it == walk_session.end()) {
      walk_session.push_back(session);
      walks.push_back(WalkInput{map.sessions[static_cast<size_t>(session)].name,
                                std::vector<std::vector<FrameOutcome>>(seed_frames.size())});
      it = walk_session.end() - 1;
    }
    WalkInput& w = walks[static_cast<size_t>(it - walk_session.begin())];
    for (size_t s = 0; s < seed_frames.size(); ++s) w.by_seed[s].push_back(seed_frames[s][i]);
  }
  return walks;
}

std::string walk_calibration_words(const nlohmann::json& c) {
  if (!c.at("fitted").get<bool>()) return "not fitted";
  const bool adds = c.at("adds").get<bool>();
  const bool agreement = !c.at("agreement").is_null();
  return adds && agreement ? "fitted, with agreement" : adds ? "fitted" : "agreement only";
}

void log_walks(const std::string& name, const nlohmann::json& walk) {
  const nlohmann::json s = walk_summary(walk);
  const auto mean = [&](const char* rule, const char* field) { return s.at(rule).at(field).at("mean").get<double>(); };
  spdlog::info(
      "eval: {}: walks (mean over seeds): frame rule {:.1f} reported right, precision {:.3f}; walk rule {:.1f} "
      "reported right, precision {:.3f} (walk calibration {})",
      name, mean("frame_rule", "reported_right"), mean("frame_rule", "precision"), mean("walk_rule", "reported_right"),
      mean("walk_rule", "precision"), walk_calibration_words(walk.at("calibration")));
}

// A method's precision@1 and MRR on the held-out map observations, its baselines searching the
// map observations without them (context.excluded_keypoints).
RetrievalMetrics rank_held_out(const EvalMethod& method, const MethodContext& context,
                               const std::vector<EvalQuery>& queries) {
  const std::unique_ptr<Matcher> matcher = method.make(context);
  std::vector<KeypointRanking> rankings;
  for (const EvalQuery& q : queries) {
    FrameMatches m = matcher->match(q);
    LMB_CHECK(m.ranking.size() == q.keypoints.size(), "eval: " << method.name << " ranked " << m.ranking.size()
                                                               << " of " << q.keypoints.size() << " keypoints");
    for (size_t k = 0; k < q.keypoints.size(); ++k) {
      if (q.truth[k] != kInvalidLandmarkId) rankings.push_back(KeypointRanking{std::move(m.ranking[k]), q.truth[k]});
    }
  }
  return evaluate_retrieval(rankings);
}

// Precision and recall of "success" by the inlier rule and by the calibrated rule, the PR curve
// over the calibrated probability, and both rules at each RANSAC budget and seed of the sweep.
nlohmann::json pose_confidence_report(const MethodResult& r, const CalibrationFit& fit, int default_iterations) {
  const int64_t n = r.pose.num_frames;
  const auto rule = [n](int64_t localized, int64_t correct) {
    return nlohmann::json{{"frames_localized", localized},
                          {"frames_correct", correct},
                          {"precision", localized > 0 ? static_cast<double>(correct) / localized : 0.0},
                          {"recall", n > 0 ? static_cast<double>(correct) / n : 0.0}};
  };
  nlohmann::json j = {
      {"calibration", fit.to_json()}, {"inlier_rule", rule(r.pose.num_localized, r.pose.num_correct)}, {"frames", n}};
  if (!fit.fitted) return j;
  std::vector<FrameOutcome> frames = r.frames;
  int64_t localized = 0, correct = 0;
  nlohmann::json probability = nlohmann::json::array();
  for (size_t i = 0; i < frames.size(); ++i) {
    const double p = fit.calibration.probability(frames[i].evidence);
    probability.push_back(p);
    frames[i].confidence = p;
    if (!frames[i].localized || p < fit.calibration.threshold) continue;
    ++localized;
    correct += r.pose.correct[i];
  }
  j["calibrated_rule"] = rule(localized, correct);
  j["calibrated_rule"]["threshold"] = fit.calibration.threshold;
  const PoseMetrics curve = evaluate_poses(frames, PoseThresholds{});
  nlohmann::json pr = nlohmann::json::array();
  for (const PosePrPoint& pt : curve.pr_curve) {
    pr.push_back({{"threshold", pt.threshold}, {"precision", pt.precision}, {"recall", pt.recall}});
  }
  j["confidence_pr_curve"] = pr;
  j["confidence_auc"] = curve.auc;
  j["frame_confidence"] = probability;
  nlohmann::json sweep = nlohmann::json::array();
  const PoseSweep& s = r.sweep;
  for (size_t b = 0; b < s.iterations.size() && !s.calibrated_localized.empty(); ++b) {
    nlohmann::json seeds = nlohmann::json::array();
    for (size_t k = 0; k < s.seeds.size(); ++k) {
      seeds.push_back({{"seed", s.seeds[k]},
                       {"inlier_rule", rule(s.frames_localized[b][k], s.frames_correct[b][k])},
                       {"calibrated_rule", rule(s.calibrated_localized[b][k], s.calibrated_correct[b][k])}});
    }
    sweep.push_back({{"ransac_iterations", s.iterations[b]},
                     {"default_budget", s.iterations[b] == default_iterations},
                     {"seeds", seeds}});
  }
  j["sweep"] = sweep;
  return j;
}

nlohmann::json settings_json(const EvalOptions& a, const nlohmann::json& build, const nlohmann::json& parameters) {
  nlohmann::json thresholds = nlohmann::json::array();
  for (const PoseThresholds& t : a.pose_thresholds) {
    thresholds.push_back(
        {{"max_position_error_m", t.max_position_error_m}, {"max_rotation_error_deg", t.max_rotation_error_deg}});
  }
  return {{"model", a.model},
          {"map", a.map},
          {"top_k", a.top_k},
          {"landmarkboost_min_margin", json_number_or_string(a.min_margin)},
          {"max_correspondences", a.max_correspondences},
          {"ransac_iterations", a.pose.max_iterations},
          {"inlier_threshold_px", a.pose.max_reprojection_error_px},
          {"min_inliers", a.pose.min_inliers},
          {"ransac_seed", a.pose.seed},
          {"prosac", a.pose.progressive_sampling},
          {"pose_thresholds", thresholds},
          {"ransac_sweep_iterations", a.sweep.iterations},
          {"ransac_sweep_seeds", a.sweep.seeds},
          {"calibration_frames", a.calibration.max_frames},
          {"target_precision", a.calibration.target_precision},
          {"hamming_backend", a.hamming_backend},
          {"pca_dims", a.pca_dims},
          {"ratio", a.ratio},
          {"method_parameters", parameters},
          {"threads", 1},
          {"index_build_seconds", build},
          {"machine", {{"cpu_model", machine_info().cpu_model}, {"logical_cores", machine_info().logical_cores}}}};
}

std::string cpu_line(const nlohmann::json& cpu) {
  std::string line;
  for (const auto& [name, ms] : cpu.items()) {
    char cell[128];
    std::snprintf(cell, sizeof(cell), "%s%s %.1f", line.empty() ? "" : ", ", name.c_str(), ms.get<double>());
    line += cell;
  }
  return "thread CPU ms per frame (matching + pose; the table's times are wall clock): " + line + "\n";
}

}  // namespace

std::vector<char> check_model_fits_map(const Model& model, const std::string& model_name, const LandmarkMap& map,
                                       const std::string& map_name) {
  LMB_CHECK(map.descriptor_bytes == model.descriptor_bytes(),
            map_name << ": " << map.descriptor_bytes << "-byte descriptors, but " << model_name << " expects "
                     << model.descriptor_bytes() << " (a model of another detector?)");
  std::vector<char> is_class(map.landmarks.size(), 0);
  for (int32_t c = 0; c < model.num_classes(); ++c) {
    const landmark_t l = model.class_landmark(c);
    LMB_CHECK(l >= 0 && l < static_cast<landmark_t>(map.landmarks.size()),
              model_name << ": class " << c << " is landmark " << l << ", but " << map_name << " has "
                         << map.landmarks.size() << " landmarks (the model was trained on another map)");
    const double d = (map.landmarks[l].position - model.class_position(c)).norm();
    LMB_CHECK(d <= 1e-6 * std::max(1.0, map.landmarks[l].position.norm()),
              model_name << ": class " << c << " (landmark " << l << ") lies " << d << " m from that landmark in "
                         << map_name << " (the model was trained on another map)");
    is_class[l] = 1;
  }
  return is_class;
}

// What the runs of every method add to the report.
struct MethodsOutcome {
  std::vector<MethodResult> results;                       // per method
  std::vector<std::vector<MethodResult>> session_results;  // per selected session, per method
  nlohmann::json build = nlohmann::json::object(), ranks = nlohmann::json::object();
  nlohmann::json cpu = nlohmann::json::object(), parameters = nlohmann::json::object();
  nlohmann::json held_methods = nlohmann::json::object(), confidence = nlohmann::json::object();
  size_t held_frames = 0, held_keypoints = 0;
};

// Each method in turn: its pose calibration, the queries, the outside frames and the held-out map
// observations.
MethodsOutcome run_methods(const EvalOptions& a, const std::shared_ptr<const Model>& model, const LandmarkMap& map,
                           const std::vector<EvalQuery>& queries, const std::vector<size_t>& query_session,
                           size_t num_sessions) {
  MethodsOutcome o;
  o.session_results.resize(num_sessions);
  // The held-out map observations of the model's training run (the validation column).
  std::vector<int64_t> held;
  std::vector<EvalQuery> held_queries;
  if (a.training_set) {
    std::vector<landmark_t> classes;
    for (int32_t c = 0; c < model->num_classes(); ++c) classes.push_back(model->class_landmark(c));
    held = held_out_observations(map, classes, *a.training_set);
    held_queries = held_out_frames(map, held);
    o.held_frames = held_queries.size();
    o.held_keypoints = held.size();
    spdlog::info("eval: {} held-out map observations in {} map frames (validation_fraction {}, seed {})", held.size(),
                 held_queries.size(), a.training_set->validation_fraction, a.training_set->seed);
  }

  const MethodContext context{model, &map, &a};
  MethodContext held_context{model, &map, &a, &held};
  held_context.excluded_from_fusion = true;
  // Every method's calibration frames: those the model's training held out (the run's options, or
  // the defaults), else every n-th map frame.
  const PoseCalibrationOptions calibration =
      with_holdout_frames(a.calibration, map, a.training_set.value_or(training_set_of(std::nullopt)));
  const std::vector<int64_t> calibration_keypoints =
      calibration_frame_keypoints(map, calibration_frames(map, calibration));
  MethodContext calibration_context{model, &map, &a, &calibration_keypoints};
  calibration_context.accept_only = true;
  calibration_context.excluded_from_fusion = true;
  const std::vector<EvalQuery> outside = outside_frames(map);
  MethodContext outside_context = context;
  outside_context.accept_only = true;
  // A cross-fitted run: each fold of the frames is matched by the method as it is without it (the
  // fold model; the baselines' index without the fold's observations).
  const std::vector<FoldModel> folds = fold_models_of_run(a.run_dir, map, a.vocab, "eval");
  std::vector<std::vector<int64_t>> fold_keypoints;
  for (const FoldModel& fold : folds) fold_keypoints.push_back(calibration_frame_keypoints(map, fold.frames));
  for (const std::string& name : a.method_names()) {
    const Clock::time_point t0 = Clock::now();
    const EvalMethod& method = find_eval_method(name);
    // The method's pose calibration, fitted on map frames (train/eval/pose_calibration_fit.h); the
    // descriptor baselines search an index without the calibration frames' observations.
    const CalibrationFit fit = [&] {
      if (folds.empty()) {
        const std::unique_ptr<Matcher> matcher = method.make(calibration_context);
        return fit_method_calibration(*matcher, map, a.pose, a.max_correspondences, a.pose_thresholds.front(),
                                      calibration);
      }
      std::vector<std::unique_ptr<Matcher>> matchers;
      std::vector<CalibrationFold> calibration_folds;
      for (size_t k = 0; k < folds.size(); ++k) {
        MethodContext fold_context{folds[k].model, &map, &a, &fold_keypoints[k]};
        fold_context.accept_only = true;
        fold_context.excluded_from_fusion = true;
        matchers.push_back(method.make(fold_context));
        calibration_folds.push_back(CalibrationFold{matchers.back().get(), folds[k].frames});
      }
      return fit_cross_fitted_calibration(calibration_folds, map, a.pose, a.max_correspondences,
                                          a.pose_thresholds.front(), calibration);
    }();
    spdlog::info(
        "eval: {}: pose calibration on {} map frames{}: {} poses ({} right, {} elsewhere){}", name, fit.num_frames,
        !folds.empty()               ? fmt::format(", cross-fitted on the run's {} fold models", folds.size())
        : calibration.frames.empty() ? std::string()
        : a.training_set             ? std::string(" held out of training by the run")
                         : std::string(" the default training options hold out (--run RUN_DIR: the run's own)"),
        fit.num_poses, fit.num_right, fit.num_elsewhere,
        !fit.fitted            ? std::string(", not fitted")
        : fit.saw_wrong_pose() ? fmt::format(", operating point {:.4f}", fit.calibration.threshold)
                               : std::string(", none wrong: every pose the inlier rule finds is reported"));
    MethodRun run = evaluate_method(method, context, queries, query_session, num_sessions, fit);
    o.confidence[name] = pose_confidence_report(run.result, fit, a.pose.max_iterations);
    std::vector<std::vector<FrameOutcome>> outside_by_seed;
    o.confidence[name]["outside"] =
        evaluate_outside(method, outside_context, outside, fit, run.result.sweep.seeds, &outside_by_seed);
    if (fit.fitted) {
      const WalkCalibrationFit walk_fit = fit_walk_calibration_on_map(map, fit, calibration);
      o.confidence[name]["walk"] = evaluate_walks(query_walks(map, queries, run.seed_frames), outside_by_seed, fit,
                                                  walk_fit, run.result.sweep.seeds, a.pose_thresholds.front());
      log_walks(name, o.confidence[name]["walk"]);
    }
    if (!outside.empty()) {
      spdlog::info("eval: {}: {} of {} outside frames localized by the inlier rule, {} by the calibrated rule", name,
                   o.confidence[name]["outside"]["localized_inlier_rule"].get<int64_t>(), outside.size(),
                   o.confidence[name]["outside"].value("localized_calibrated", int64_t{0}));
    }
    spdlog::info(
        "eval: {}: P@1 {:.4f}, MRR {:.4f}, match precision {:.4f}, match recall {:.4f}, {}/{} frames "
        "correct, {:.2f} ms/frame matching ({:.1f} s)",
        name, run.result.retrieval.precision_at_1, run.result.retrieval.mrr, run.result.matches.match_precision,
        run.result.matches.match_recall, run.result.pose.num_correct, run.result.pose.num_frames,
        run.result.pose.mean_match_ms, ms_since(t0) / 1000.0);
    if (!held.empty()) {
      const RetrievalMetrics r = rank_held_out(method, held_context, held_queries);
      o.held_methods[name] = {{"precision_at_1", r.precision_at_1}, {"mrr", r.mrr}};
      spdlog::info("eval: {}: held-out map observations P@1 {:.4f}, MRR {:.4f}", name, r.precision_at_1, r.mrr);
    }
    o.build[name] = run.build_seconds;
    o.ranks[name] = run.ranks;
    o.cpu[name] = run.cpu_ms_per_frame;
    o.parameters[name] = run.parameters;
    o.results.push_back(std::move(run.result));
    for (size_t i = 0; i < num_sessions; ++i) o.session_results[i].push_back(std::move(run.sessions[i]));
  }

  return o;
}

// One report per selected query session, each with every method's figures.
nlohmann::json session_reports(const LandmarkMap& map, const std::vector<int32_t>& sessions,
                               const std::vector<std::vector<MethodResult>>& session_results) {
  nlohmann::json reports = nlohmann::json::array();
  for (size_t i = 0; i < sessions.size(); ++i) {
    const MapSession& session = map.sessions[static_cast<size_t>(sessions[i])];
    nlohmann::json r = {{"name", session.name},
                        {"kind", session_kind_name(session.kind)},
                        {"frames", session_results[i].front().pose.num_frames},
                        {"keypoints_with_class_truth", session_results[i].front().retrieval.num_with_truth},
                        {"methods", nlohmann::json::object()}};
    for (const MethodResult& m : session_results[i]) r["methods"][m.name] = session_method_report(m);
    reports.push_back(r);
  }
  return reports;
}

EvalResult run_evaluation(const EvalOptions& a) {
  a.check();
  cv::setNumThreads(1);
  const std::shared_ptr<const Model> model = Model::load(a.model);
  const LandmarkMap map = read_map_h5(a.map);
  const std::vector<char> is_class = check_model_fits_map(*model, a.model, map, a.map);
  const std::vector<int32_t> sessions = selected_sessions(map, a);
  const std::vector<EvalQuery> queries = query_frames(map, is_class, sessions, a);
  std::vector<size_t> query_session;
  for (const EvalQuery& q : queries) {
    const int32_t s = map.frames[q.frame].session;
    const auto it = std::lower_bound(sessions.begin(), sessions.end(), s);
    query_session.push_back(static_cast<size_t>(it - sessions.begin()));
  }
  int64_t with_class_truth = 0;
  const DatasetCounts counts = count_dataset(map, queries, &with_class_truth);
  LMB_CHECK(with_class_truth > 0, a.map << ": none of the " << counts.query_keypoints
                                        << " query keypoints observes one of the model's " << model->num_classes()
                                        << " landmarks (were the query frames mapped jointly with the map?)");
  const std::vector<std::string> names = a.method_names();
  std::string method_list;
  for (const std::string& m : names) method_list += (method_list.empty() ? "" : ", ") + m;
  spdlog::info(
      "eval: {} query frames, {} keypoints ({} with a true landmark, {} of them a model class), "
      "model {} classes, {} stumps; methods: {}",
      counts.query_frames, counts.query_keypoints, counts.query_keypoints_with_truth, with_class_truth,
      model->num_classes(), model->data().stumps.size(), method_list);

  MethodsOutcome m = run_methods(a, model, map, queries, query_session, sessions.size());

  EvalResult out;
  out.report = build_report(counts, m.results);
  for (const auto& [name, ms] : m.cpu.items()) out.report["methods"][name]["cpu_ms_per_frame"] = ms;
  for (const auto& [name, c] : m.confidence.items()) out.report["methods"][name]["pose_confidence"] = c;
  out.report["model_calibration"] = model->calibrated()
                                        ? nlohmann::json{{"calibrated", true},
                                                         {"threshold", model->calibration().threshold},
                                                         {"target_precision", model->calibration().target_precision},
                                                         {"poses", model->calibration().num_samples}}
                                        : nlohmann::json{{"calibrated", false}};
  out.report["dataset"]["model_classes"] = model->num_classes();
  out.report["dataset"]["query_keypoints_with_class_truth"] = with_class_truth;
  out.report["settings"] = settings_json(a, m.build, m.parameters);
  nlohmann::json session_names = nlohmann::json::array();
  for (int32_t s : sessions) session_names.push_back(map.sessions[static_cast<size_t>(s)].name);
  out.report["dataset"]["query_sessions"] = session_names;
  out.report["sessions"] = session_reports(map, sessions, m.session_results);
  if (a.training_set) {
    out.report["held_out_map_observations"] = {{"frames", m.held_frames},
                                               {"keypoints", m.held_keypoints},
                                               {"validation_fraction", a.training_set->validation_fraction},
                                               {"min_train_observations", a.training_set->min_train_observations},
                                               {"seed", a.training_set->seed},
                                               {"methods", m.held_methods}};
  }
  out.report["generalization_gap"] = generalization_gap(out.report);
  nlohmann::json frame_names = nlohmann::json::array();
  for (const EvalQuery& q : queries) frame_names.push_back(map.frames[q.frame].name);
  out.report["query_frame_names"] = frame_names;
  out.keypoint_ranks = {{"frames", frame_names},
                        {"truth_rank", m.ranks},
                        {"note",
                         "per method, per query frame, per keypoint: 1-based rank of the true landmark "
                         "among the method's candidates, 0 when absent or the keypoint has no true "
                         "landmark among the model's classes"}};
  char heading[512];
  std::snprintf(heading, sizeof(heading),
                "Results on %lld query frames, %lld query keypoints with a true landmark among the model's %d "
                "classes (%s):\n",
                static_cast<long long>(counts.query_frames), static_cast<long long>(with_class_truth),
                model->num_classes(), machine_info().summary().c_str());
  out.heading = heading;
  out.table = format_results_table(out.report);
  out.gap_table = format_generalization_gap(out.report);
  out.confidence_table = format_confidence_table(out.report) + format_walk_table(out.report);
  out.cpu_line = cpu_line(m.cpu);
  return out;
}

void attach_training_summary(nlohmann::json& report, const std::filesystem::path& run_dir) {
  const std::filesystem::path summary = run_dir / "summary.json";
  std::ifstream in(summary);
  LMB_CHECK(in.good(),
            "eval: --run " << run_dir.string() << ": no summary.json (not a finished `lboost train` run dir)");
  try {
    report["training"] = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    LMB_FAIL(summary.string() << ": not JSON (" << e.what() << ")");
  }
}

}  // namespace lmb
