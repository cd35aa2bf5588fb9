#include "train/eval/map_localization.h"

#include <atomic>
#include <cstdio>
#include <exception>
#include <map>
#include <mutex>
#include <thread>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/stats.h"
#include "infer/detail/scoring_index.h"
#include "infer/walk_confidence.h"
#include "train/eval/metrics.h"
#include "train/eval/report.h"

namespace lmb {

namespace {

struct LocalizedFrame {
  LocalizeResult result;
  // Per keypoint: its accepted match (the best match left after background rejection, or
  // kInvalidLandmarkId) and its true landmark when that landmark is a model class.
  std::vector<KeypointMatch> matches;
};

std::vector<frame_t> select_frames(const LandmarkMap& map, const std::vector<std::string>& names) {
  std::vector<frame_t> frames;
  if (names.empty()) {
    for (frame_t f = 0; f < map.num_frames(); ++f) {
      if (map.frames[f].is_query) frames.push_back(f);
    }
    LMB_CHECK(!frames.empty(), "localize: the map has no query frames (give --queries)");
    return frames;
  }
  for (const std::string& name : names) {
    frame_t found = kInvalidFrameId;
    for (frame_t f = 0; f < map.num_frames(); ++f) {
      if (map.frames[f].name == name) found = f;
    }
    LMB_CHECK(found != kInvalidFrameId, "localize: --queries: no frame named '" << name << "' in the map");
    frames.push_back(found);
  }
  return frames;
}

LocalizedFrame localize_frame(const Localizer& localizer, const LandmarkMap& map, const std::vector<char>& is_class,
                              frame_t f) {
  const MapFrame& frame = map.frames[f];
  const std::vector<Keypoint> keypoints(map.keypoints.begin() + frame.first_keypoint,
                                        map.keypoints.begin() + frame.first_keypoint + frame.num_keypoints);
  LocalizedFrame o;
  o.result = localizer.localize(map.cameras[frame.camera], keypoints, map.descriptor(frame.first_keypoint),
                                frame.gravity_in_cam);
  for (int32_t k = 0; k < frame.num_keypoints; ++k) {
    const landmark_t truth = map.keypoint_landmark[frame.first_keypoint + k];
    const bool has_match = o.result.matches.count(k) > 0;
    o.matches.push_back(KeypointMatch{has_match ? o.result.matches.of(k)[0].landmark : kInvalidLandmarkId,
                                      truth != kInvalidLandmarkId && is_class[truth] ? truth : kInvalidLandmarkId});
  }
  return o;
}

// Every frame, --threads at a time.
std::vector<LocalizedFrame> localize_all(const Localizer& localizer, const LandmarkMap& map,
                                         const std::vector<char>& is_class, const std::vector<frame_t>& frames,
                                         int threads) {
  std::vector<LocalizedFrame> outcomes(frames.size());
  std::atomic<size_t> next{0};
  std::vector<std::thread> pool;
  std::exception_ptr error;
  std::mutex error_mutex;
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back([&] {
      for (size_t i = next++; i < frames.size(); i = next++) {
        try {
          outcomes[i] = localize_frame(localizer, map, is_class, frames[i]);
        } catch (...) {
          std::lock_guard<std::mutex> lock(error_mutex);
          if (!error) error = std::current_exception();
        }
      }
    });
  }
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
  return outcomes;
}

// One frame's entry of the output: pose, errors, timings and matches [keypoint, rank, landmark,
// score, inlier] (the pose's correspondences, or every ranked match with --all-matches).
nlohmann::json frame_json(const MapFrame& frame, const LocalizedFrame& o, bool all_matches) {
  const LocalizeResult& r = o.result;
  nlohmann::json jf;
  jf["name"] = frame.name;
  // success: localized (the calibrated rule with a calibrated model, else the inlier rule);
  // pose_found: the inlier rule alone; confidence: the calibrated probability (-1 uncalibrated).
  jf["success"] = r.localized;
  jf["pose_found"] = r.pose.success;
  jf["confidence"] = r.confidence;
  jf["cam_from_world"] = cam_from_world_json(r.pose.cam_from_world);
  jf["num_inliers"] = r.pose.num_inliers;
  const RansacStats& st = r.pose.stats;
  jf["ransac"] = {{"iterations", st.iterations},
                  {"models", st.models},
                  {"refinements", st.refinements},
                  {"subset_size", st.subset_size},
                  {"stop_subset", st.stop_subset},
                  {"score", st.score},
                  {"runner_up_inliers", st.runner_up_inliers},
                  {"runner_up_shared", st.runner_up_shared}};
  jf["num_correspondences"] = r.correspondence_keypoint.size();
  jf["num_keypoints"] = frame.num_keypoints;
  int matched = 0;
  for (const KeypointMatch& m : o.matches) matched += m.accepted != kInvalidLandmarkId;
  jf["num_matched_keypoints"] = matched;
  if (r.pose.success) {  // the pose RANSAC found, whether trusted or not
    jf["position_error_m"] = position_error(r.pose.cam_from_world, frame.cam_from_world);
    jf["rotation_error_deg"] = rotation_error_deg(r.pose.cam_from_world, frame.cam_from_world);
  }
  jf["timings_ms"] = {{"embedding", r.timings.embedding_ms},
                      {"classification", r.timings.classification_ms},
                      {"pose", r.timings.pose_ms},
                      {"total", r.timings.total_ms}};
  std::vector<char> inlier(r.matches.matches.size(), 0), used(r.matches.matches.size(), 0);
  for (size_t c = 0; c < r.correspondence_match.size(); ++c) {
    used[r.correspondence_match[c]] = 1;
    if (r.pose.inlier_mask[c]) inlier[r.correspondence_match[c]] = 1;
  }
  nlohmann::json jm = nlohmann::json::array();
  for (int32_t k = 0; k < r.matches.num_keypoints(); ++k) {
    for (int32_t j = 0; j < r.matches.count(k); ++j) {
      const int32_t idx = r.matches.begin[k] + j;
      if (!all_matches && !used[idx]) continue;
      const ClassMatch& m = r.matches.matches[idx];
      jm.push_back({k, j, m.landmark, m.score, inlier[idx] != 0});
    }
  }
  jf["matches"] = std::move(jm);
  return jf;
}

// Each frame's verdict when the selected frames of each query session are tracked as one walk, in
// map order (WalkTracker: the frame rule, or the walk rule while a trusted pose is at most a few
// frames back). Sequential over the per-frame results, so it does not depend on the threads that
// localized them. Uncalibrated model: the frame's own verdict.
std::vector<WalkVerdict> walk_verdicts(const Model& model, const Localizer& localizer, const LandmarkMap& map,
                                       const std::vector<frame_t>& frames,
                                       const std::vector<LocalizedFrame>& outcomes) {
  std::vector<WalkVerdict> out(frames.size());
  if (!model.calibrated()) {
    for (size_t i = 0; i < frames.size(); ++i) out[i].localized = outcomes[i].result.localized;
    return out;
  }
  PoseCalibration frame_rule = model.calibration();
  if (localizer.options().min_confidence >= 0) frame_rule.threshold = localizer.options().min_confidence;
  std::map<int32_t, WalkTracker> trackers;
  for (size_t i = 0; i < frames.size(); ++i) {
    const int32_t session = map.frames[frames[i]].session;
    WalkTracker& tracker = trackers.try_emplace(session, frame_rule, model.walk_calibration()).first->second;
    const LocalizeResult& r = outcomes[i].result;
    out[i] = tracker.update(r.pose.success, r.pose.cam_from_world, r.evidence);
  }
  return out;
}

// The summary over the frames (also printed): pose counts and errors, the accepted matches'
// metrics (train/eval/metrics.h: match_precision, match_recall, background_rejection_rate, the
// same definitions as `lboost eval`'s report) and the mean timings.
nlohmann::json summary_json(const LandmarkMap& map, const std::vector<frame_t>& frames,
                            const std::vector<LocalizedFrame>& outcomes, const std::vector<WalkVerdict>& walk,
                            bool localizer_calibrated) {
  std::vector<double> position_errors, rotation_errors;
  int localized = 0, pose_found = 0, pose_found_right = 0, within_5cm_1deg = 0, within_20cm_5deg = 0;
  int walk_localized = 0, walk_right = 0, walk_added = 0, walk_refused = 0;
  double total_ms = 0, embedding_ms = 0, classification_ms = 0, pose_ms = 0;
  std::vector<KeypointMatch> matches;
  for (size_t i = 0; i < frames.size(); ++i) {
    const LocalizeResult& r = outcomes[i].result;
    matches.insert(matches.end(), outcomes[i].matches.begin(), outcomes[i].matches.end());
    total_ms += r.timings.total_ms;
    embedding_ms += r.timings.embedding_ms;
    classification_ms += r.timings.classification_ms;
    pose_ms += r.timings.pose_ms;
    const Rigid3d& truth = map.frames[frames[i]].cam_from_world;
    pose_found += r.pose.success;
    pose_found_right += r.pose.success && pose_within(r.pose.cam_from_world, truth, PoseThresholds{0.20, 5.0});
    walk_refused += walk[i].agreement_applies && !walk[i].agrees;
    if (walk[i].localized) {
      ++walk_localized;
      walk_right += pose_within(r.pose.cam_from_world, truth, PoseThresholds{0.20, 5.0});
      walk_added += walk[i].by_walk;
    }
    if (!r.localized) continue;
    ++localized;
    position_errors.push_back(position_error(r.pose.cam_from_world, truth));
    rotation_errors.push_back(rotation_error_deg(r.pose.cam_from_world, truth));
    within_5cm_1deg += pose_within(r.pose.cam_from_world, truth, PoseThresholds{0.05, 1.0});
    within_20cm_5deg += pose_within(r.pose.cam_from_world, truth, PoseThresholds{0.20, 5.0});
  }
  const MatchMetrics mm = evaluate_matches(matches);
  const double nf = static_cast<double>(frames.size());
  return {{"frames", frames.size()},
          {"calibrated", localizer_calibrated},
          {"localized", localized},
          {"precision_20cm_5deg", localized > 0 ? static_cast<double>(within_20cm_5deg) / localized : 0.0},
          {"pose_found", pose_found},
          {"pose_found_within_20cm_5deg", pose_found_right},
          {"within_5cm_1deg", within_5cm_1deg},
          {"within_20cm_5deg", within_20cm_5deg},
          {"walk",
           {{"localized", walk_localized},
            {"within_20cm_5deg", walk_right},
            {"by_walk_rule", walk_added},
            {"disagreeing", walk_refused},
            {"precision_20cm_5deg", walk_localized > 0 ? static_cast<double>(walk_right) / walk_localized : 0.0}}},
          {"median_position_error_m", median(position_errors)},
          {"median_rotation_error_deg", median(rotation_errors)},
          {"match_recall", mm.match_recall},
          {"keypoints_with_class_truth", mm.num_with_truth},
          {"match_precision", mm.match_precision},
          {"accepted_matches", mm.num_accepted},
          {"background_rejection_rate", mm.background_rejection_rate},
          {"background_keypoints", mm.num_background},
          {"ms_per_frame",
           {{"embedding", embedding_ms / nf},
            {"classification", classification_ms / nf},
            {"pose", pose_ms / nf},
            {"total", total_ms / nf}}}};
}

}  // namespace

nlohmann::json localize_map_frames(const std::shared_ptr<const Model>& model, const LandmarkMap& map,
                                   const std::vector<char>& is_class, const MapLocalizationOptions& o) {
  LMB_CHECK(o.threads >= 1 && o.threads <= 256, "localize: --threads = " << o.threads << " must be in 1..256");
  const Localizer localizer(model, o.localizer);
  const std::vector<frame_t> frames = select_frames(map, o.queries);
  spdlog::info("localize: {} frames, model {} classes, {} stumps, {} used dims, {} scoring, {} thread(s)",
               frames.size(), model->num_classes(), model->data().stumps.size(), model->scoring().used_dims().size(),
               o.localizer.classifier.use_inverted_file ? "inverted-file" : "dense", o.threads);
  const std::vector<LocalizedFrame> outcomes = localize_all(localizer, map, is_class, frames, o.threads);

  nlohmann::json out;
  out["options"] = {{"top_k", o.localizer.classifier.top_k},
                    {"use_inverted_file", o.localizer.classifier.use_inverted_file},
                    {"inverted_file_words", o.localizer.classifier.inverted_file_words},
                    {"min_margin", json_number_or_string(o.localizer.classifier.min_margin)},
                    {"pose_top_k", o.localizer.pose_top_k},
                    {"max_correspondences", o.localizer.max_correspondences},
                    {"ransac_iterations", o.localizer.pose.max_iterations},
                    {"max_reprojection_error_px", o.localizer.pose.max_reprojection_error_px},
                    {"min_inliers", o.localizer.pose.min_inliers},
                    {"seed", o.localizer.pose.seed},
                    {"prosac", o.localizer.pose.progressive_sampling}};
  const std::vector<WalkVerdict> walk = walk_verdicts(*model, localizer, map, frames, outcomes);
  nlohmann::json jframes = nlohmann::json::array();
  for (size_t i = 0; i < frames.size(); ++i) {
    nlohmann::json jf = frame_json(map.frames[frames[i]], outcomes[i], o.all_matches);
    jf["walk"] = {{"localized", walk[i].localized},
                  {"by_walk_rule", walk[i].by_walk},
                  {"continues", walk[i].continues},
                  {"walk_confidence", walk[i].walk_confidence},
                  {"agrees", walk[i].compared ? nlohmann::json(walk[i].agrees) : nlohmann::json(nullptr)},
                  {"agreement_applies", walk[i].agreement_applies}};
    jframes.push_back(std::move(jf));
  }
  out["frames"] = std::move(jframes);
  out["summary"] = summary_json(map, frames, outcomes, walk, model->calibrated());
  // A calibration fitted on right poses only reports every pose found (the constant 0.5).
  out["summary"]["calibration_saw_wrong_pose"] =
      model->calibrated() ? nlohmann::json(!model->calibration().saw_no_wrong_pose()) : nlohmann::json(nullptr);
  out["calibration"] =
      model->calibrated()
          ? nlohmann::json{{"threshold", localizer.options().min_confidence >= 0 ? localizer.options().min_confidence
                                                                                 : model->calibration().threshold},
                           {"target_precision", model->calibration().target_precision},
                           {"walk_calibration", model->walk_calibration().has_value()}}
          : nlohmann::json(nullptr);
  return out;
}

nlohmann::json cam_from_world_json(const Rigid3d& cam_from_world) {
  const Eigen::Quaterniond& q = cam_from_world.rotation;
  const Eigen::Vector3d& t = cam_from_world.translation;
  return {{"qw", q.w()}, {"qx", q.x()}, {"qy", q.y()}, {"qz", q.z()}, {"tx", t.x()}, {"ty", t.y()}, {"tz", t.z()}};
}

std::string map_localization_summary_line(const nlohmann::json& s, int threads) {
  const nlohmann::json& ms = s.at("ms_per_frame");
  char line[1024];
  std::snprintf(
      line, sizeof(line),
      "localize: %d/%zu frames localized (%s; precision %.3f at 20 cm/5 deg; %d/%zu with >= min-inliers inliers, %d of "
      "them right), %d within 5 cm/1 deg, %d within 20 cm/5 deg; tracked as walks %d localized (%d by the walk "
      "rule, %d poses disagreeing with the frame before), precision %.3f; median error "
      "%.3f m %.2f deg (localized frames); match recall %.3f of %lld keypoints whose true landmark is a "
      "model class, match precision %.3f of %lld accepted matches, background rejection %.3f of %lld "
      "background keypoints; %.1f ms/frame (embedding %.1f, classification %.1f, pose %.1f, %d thread(s))",
      s.at("localized").get<int>(), s.at("frames").get<size_t>(),
      !s.at("calibrated").get<bool>()               ? "uncalibrated model: inlier rule"
      : s.value("calibration_saw_wrong_pose", true) ? "calibrated confidence"
                                                    : "a calibration that saw no wrong pose: every pose found",
      s.at("precision_20cm_5deg").get<double>(), s.at("pose_found").get<int>(), s.at("frames").get<size_t>(),
      s.at("pose_found_within_20cm_5deg").get<int>(), s.at("within_5cm_1deg").get<int>(),
      s.at("within_20cm_5deg").get<int>(), s.at("walk").at("localized").get<int>(),
      s.at("walk").at("by_walk_rule").get<int>(), s.at("walk").at("disagreeing").get<int>(),
      s.at("walk").at("precision_20cm_5deg").get<double>(), s.at("median_position_error_m").get<double>(),
      s.at("median_rotation_error_deg").get<double>(), s.at("match_recall").get<double>(),
      s.at("keypoints_with_class_truth").get<long long>(), s.at("match_precision").get<double>(),
      s.at("accepted_matches").get<long long>(), s.at("background_rejection_rate").get<double>(),
      s.at("background_keypoints").get<long long>(), ms.at("total").get<double>(), ms.at("embedding").get<double>(),
      ms.at("classification").get<double>(), ms.at("pose").get<double>(), threads);
  return line;
}

}  // namespace lmb
