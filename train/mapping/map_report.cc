#include "train/mapping/map_report.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <string>

#include "train/mapping/depth_ground_truth.h"
#include "train/mapping/descriptor_nn.h"

namespace lmb {

namespace {

// printf into a string.
__attribute__((format(printf, 2, 3))) void append(std::string* out, const char* format, ...) {
  va_list args;
  va_start(args, format);
  char line[1024];
  std::vsnprintf(line, sizeof(line), format, args);
  va_end(args);
  *out += line;
}

}  // namespace

std::vector<FrameReprojection> frame_reprojection_errors(const LandmarkMap& map) {
  std::vector<FrameReprojection> out;
  for (size_t f = 0; f < map.frames.size(); ++f) {
    const MapFrame& frame = map.frames[f];
    const Camera& camera = map.cameras[static_cast<size_t>(frame.camera)];
    FrameReprojection r;
    r.frame = static_cast<frame_t>(f);
    double sum = 0;
    for (int64_t k = frame.first_keypoint; k < frame.first_keypoint + frame.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      if (l == kInvalidLandmarkId) continue;
      const Eigen::Vector3d p = frame.cam_from_world * map.landmarks[l].position;
      Eigen::Vector2d pixel;
      if (p.z() <= 1e-9 || !camera.project(p, &pixel)) continue;
      const double e = (pixel - Eigen::Vector2d(map.keypoints[k].x, map.keypoints[k].y)).norm();
      if (!std::isfinite(e)) continue;
      sum += e;
      ++r.observations;
    }
    r.mean_error_px = r.observations > 0 ? sum / static_cast<double>(r.observations) : 0.0;
    out.push_back(r);
  }
  return out;
}

nlohmann::json frame_reprojection_summary(const LandmarkMap& map, int worst) {
  std::vector<FrameReprojection> frames = frame_reprojection_errors(map);
  frames.erase(
      std::remove_if(frames.begin(), frames.end(), [](const FrameReprojection& r) { return r.observations == 0; }),
      frames.end());
  std::sort(frames.begin(), frames.end(), [](const FrameReprojection& a, const FrameReprojection& b) {
    return a.mean_error_px != b.mean_error_px ? a.mean_error_px > b.mean_error_px : a.frame < b.frame;
  });
  double sum = 0;
  for (const FrameReprojection& r : frames) sum += r.mean_error_px;
  auto at = [&](double q) {  // q-quantile of the frames' errors (frames sorted worst first)
    if (frames.empty()) return 0.0;
    const size_t k = std::min(frames.size() - 1, static_cast<size_t>((1.0 - q) * static_cast<double>(frames.size())));
    return frames[k].mean_error_px;
  };
  nlohmann::json j = {{"frames", frames.size()},
                      {"mean_px", frames.empty() ? 0.0 : sum / static_cast<double>(frames.size())},
                      {"median_px", at(0.5)},
                      {"p90_px", at(0.9)},
                      {"worst", nlohmann::json::array()}};
  for (size_t i = 0; i < frames.size() && i < static_cast<size_t>(std::max(0, worst)); ++i) {
    j["worst"].push_back({{"name", map.frames[static_cast<size_t>(frames[i].frame)].name},
                          {"mean_px", frames[i].mean_error_px},
                          {"observations", frames[i].observations}});
  }
  return j;
}

std::string frame_reprojection_text(const nlohmann::json& s) {
  std::string out;
  append(&out, "reprojection error per frame (%lld frames with landmarks): mean %.2f px, median %.2f px, p90 %.2f px",
         s["frames"].get<long long>(), s["mean_px"].get<double>(), s["median_px"].get<double>(),
         s["p90_px"].get<double>());
  if (!s["worst"].empty()) out += "; worst";
  for (const auto& w : s["worst"]) {
    append(&out, " %s %.2f px (%lld)", w["name"].get<std::string>().c_str(), w["mean_px"].get<double>(),
           w["observations"].get<long long>());
  }
  return out;
}

nlohmann::json map_statistics(const LandmarkMap& map) {
  int map_frames = 0, query_frames = 0;
  int64_t map_keypoints = 0, query_keypoints = 0, map_with = 0, query_with = 0;
  for (const MapFrame& f : map.frames) {
    (f.is_query ? query_frames : map_frames) += 1;
    (f.is_query ? query_keypoints : map_keypoints) += f.num_keypoints;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      if (map.keypoint_landmark[k] != kInvalidLandmarkId) (f.is_query ? query_with : map_with) += 1;
    }
  }
  std::vector<int32_t> obs;
  double error_sum = 0, quality_min = 0, quality_max = 0;
  int64_t at_least_5 = 0, at_least_10 = 0, with_query = 0;
  for (const Landmark& l : map.landmarks) {
    obs.push_back(l.num_map_observations);
    error_sum += l.mean_reprojection_error;
    at_least_5 += l.num_map_observations >= 5 ? 1 : 0;
    at_least_10 += l.num_map_observations >= 10 ? 1 : 0;
    with_query += l.num_query_observations > 0 ? 1 : 0;
  }
  if (!map.landmarks.empty()) {
    const auto [lo, hi] =
        std::minmax_element(map.landmarks.begin(), map.landmarks.end(),
                            [](const Landmark& a, const Landmark& b) { return a.quality < b.quality; });
    quality_min = lo->quality;
    quality_max = hi->quality;
  }
  std::sort(obs.begin(), obs.end());
  const double n = static_cast<double>(std::max<size_t>(1, obs.size()));
  nlohmann::json j;
  j["detector"] = map.detector;
  j["descriptor_bytes"] = map.descriptor_bytes;
  j["cameras"] = map.cameras.size();
  j["map_frames"] = map_frames;
  j["query_frames"] = query_frames;
  j["map_keypoints"] = map_keypoints;
  j["query_keypoints"] = query_keypoints;
  j["map_keypoints_with_landmark"] = map_with;
  j["query_keypoints_with_landmark"] = query_with;
  j["landmarks"] = map.landmarks.size();
  j["landmarks_with_5_map_observations"] = at_least_5;
  j["landmarks_with_10_map_observations"] = at_least_10;
  j["landmarks_seen_by_queries"] = with_query;
  j["map_observations_per_landmark"] = {{"mean", static_cast<double>(map_with) / n},
                                        {"median", obs.empty() ? 0 : obs[obs.size() / 2]},
                                        {"max", obs.empty() ? 0 : obs.back()}};
  j["mean_reprojection_error_px"] = error_sum / n;
  j["quality"] = {{"min", quality_min}, {"max", quality_max}};
  j["reprojection_error_per_frame"] = frame_reprojection_summary(map);
  // Per session: frames, keypoints, keypoints with a landmark, and (map sessions) landmarks that
  // only this session observes.
  const size_t num_sessions = map.sessions.size();
  std::vector<int64_t> frames(num_sessions, 0), keypoints(num_sessions, 0), with(num_sessions, 0);
  std::vector<int32_t> only(map.landmarks.size(), -1);  // the one session observing a landmark, -2 = several
  for (const MapFrame& f : map.frames) {
    const size_t s = static_cast<size_t>(f.session);
    ++frames[s];
    keypoints[s] += f.num_keypoints;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      if (l == kInvalidLandmarkId) continue;
      ++with[s];
      if (!f.is_query) only[l] = only[l] == -1 || only[l] == f.session ? f.session : -2;
    }
  }
  std::vector<int64_t> exclusive(num_sessions, 0);
  for (int32_t s : only) {
    if (s >= 0) ++exclusive[static_cast<size_t>(s)];
  }
  j["sessions"] = nlohmann::json::array();
  for (size_t s = 0; s < num_sessions; ++s) {
    nlohmann::json e = {{"name", map.sessions[s].name},
                        {"kind", session_kind_name(map.sessions[s].kind)},
                        {"frames", frames[s]},
                        {"keypoints", keypoints[s]},
                        {"keypoints_with_landmark", with[s]}};
    if (map.sessions[s].kind == SessionKind::kMap) e["landmarks_seen_only_here"] = exclusive[s];
    j["sessions"].push_back(e);
  }
  return j;
}

nlohmann::json map_report(const LandmarkMap& map, const MapReportOptions& options) {
  nlohmann::json j = map_statistics(map);
  j["detector"] = map.detector;
  j["descriptor_bytes"] = map.descriptor_bytes;
  j["cameras"] = map.cameras.size();
  j["landmarks"] = map.landmarks.size();
  if (options.hamming_nn) {
    const auto start = std::chrono::steady_clock::now();
    const HammingNnStats nn = evaluate_hamming_nn(map, options.threads);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    j["hamming_nn"] = {{"queries", nn.num_queries},
                       {"database", nn.num_database},
                       {"correct", nn.num_correct},
                       {"precision_at_1", nn.precision_at_1},
                       {"mean_nn_distance_bits", nn.mean_nn_distance},
                       {"mean_true_landmark_distance_bits", nn.mean_true_nn_distance},
                       {"seconds", seconds}};
  }
  if (!options.depth_collection.empty()) {
    const MapAccuracy a = check_map_against_depth(map, options.depth_collection);
    j["depth_check"] = {{"collection", options.depth_collection},
                        {"landmarks_checked", a.landmarks_checked},
                        {"observations_checked", a.observations_checked},
                        {"observations_without_depth", a.observations_without_depth},
                        {"mean_track_purity", a.mean_track_purity},
                        {"observation_purity", a.observation_purity},
                        {"pure_track_share", a.pure_track_share},
                        {"median_position_error_m", a.median_position_error_m},
                        {"mean_position_error_m", a.mean_position_error_m},
                        {"p90_position_error_m", a.p90_position_error_m}};
  }
  return j;
}

namespace {

nlohmann::json camera_json(const Camera& camera) {
  return {{"model", camera_model_name(camera.model)},
          {"width", camera.width},
          {"height", camera.height},
          {"params", camera.params},
          {"mean_focal_px", camera.mean_focal_length()}};
}

}  // namespace

nlohmann::json mapper_statistics(const MapperStats& s) {
  nlohmann::json j = {{"map_frames", s.num_map_frames},
                      {"query_frames", s.num_query_frames},
                      {"keypoints", s.num_keypoints},
                      {"pairs", s.num_pairs},
                      {"pairs_rule", s.pairs_by_overlap ? "view overlap" : "camera distance"},
                      {"matches", s.num_matches},
                      {"tracks", s.num_tracks},
                      {"landmarks", s.num_landmarks},
                      {"query_keypoints_with_landmark", s.num_query_observations},
                      {"mean_reprojection_error_px", s.mean_reprojection_error_px},
                      {"seconds",
                       {{"detect", s.detect_seconds},
                        {"match", s.match_seconds},
                        {"triangulate", s.triangulate_seconds},
                        {"refine", s.refine_seconds},
                        {"total", s.total_seconds}}}};
  if (s.pairs_by_overlap) {
    const OverlapPairStats& o = s.overlap;
    j["overlap_pairs"] = {
        {"map_pairs_by_pose", s.num_first_pass_pairs},
        {"first_map_points", s.num_first_pass_points},
        {"query_pairs_by_pose", s.num_query_pose_pairs},
        {"query_pairs_by_overlap", o.pairs},
        {"query_frames_with_partner", o.query_frames_with},
        {"query_frames_without_partner", o.query_frames_without},
        {"mean_partners", o.mean_partners},
        {"partner_distance",
         {{"median", o.median_partner_distance}, {"p90", o.p90_partner_distance}, {"max", o.max_partner_distance}}}};
  }
  if (!s.focal_check.empty()) {
    j["focal_check"] = nlohmann::json::array();
    for (const FocalCheck& f : s.focal_check) {
      j["focal_check"].push_back(
          {{"focal_px", f.focal_px},
           {"fitted_focal_px", f.fitted_focal_px},
           {"observations", f.observations},
           {"mean_reprojection_error_px", {{"before", f.error_before_px}, {"after", f.error_after_px}}}});
    }
  }
  if (!s.cameras_after.empty()) {
    nlohmann::json cameras = nlohmann::json::array();
    for (size_t c = 0; c < s.cameras_after.size(); ++c) {
      cameras.push_back({{"before", camera_json(s.cameras_before[c])}, {"after", camera_json(s.cameras_after[c])}});
    }
    j["camera_refinement"] = {{"rounds", s.refine_rounds},
                              {"cameras", cameras},
                              {"mean_reprojection_error_px",
                               {{"before", s.reprojection_error_before_px}, {"after", s.reprojection_error_after_px}}},
                              {"landmarks", {{"before", s.landmarks_before}, {"after", s.num_landmarks}}},
                              {"query_keypoints_with_landmark",
                               {{"before", s.query_observations_before}, {"after", s.num_query_observations}}}};
  }
  return j;
}

std::string camera_refinement_text(const MapperStats& s) {
  std::string out;
  for (size_t c = 0; c < s.cameras_after.size(); ++c) {
    const Camera& a = s.cameras_before[c];
    const Camera& b = s.cameras_after[c];
    append(&out,
           "camera %zu (%s %dx%d): focal %.2f -> %.2f px (%+.2f%%), principal point (%.2f, %.2f) -> (%.2f, %.2f)\n", c,
           camera_model_name(a.model).c_str(), a.width, a.height, a.mean_focal_length(), b.mean_focal_length(),
           100.0 * (b.mean_focal_length() / a.mean_focal_length() - 1.0), a.principal_point().x(),
           a.principal_point().y(), b.principal_point().x(), b.principal_point().y());
  }
  if (!s.cameras_after.empty()) {
    append(&out,
           "%d round(s); landmark mean reprojection error %.3f -> %.3f px, landmarks %lld -> %lld, query keypoints "
           "with a landmark %lld -> %lld\n",
           s.refine_rounds, s.reprojection_error_before_px, s.reprojection_error_after_px,
           static_cast<long long>(s.landmarks_before), static_cast<long long>(s.num_landmarks),
           static_cast<long long>(s.query_observations_before), static_cast<long long>(s.num_query_observations));
  }
  return out;
}

std::string map_report_text(const nlohmann::json& j) {
  std::string out;
  append(&out, "%s, %d-byte descriptors, %lld camera(s)\n", j["detector"].get<std::string>().c_str(),
         j["descriptor_bytes"].get<int>(), j["cameras"].get<long long>());
  append(&out, "frames: %d map, %d query\n", j["map_frames"].get<int>(), j["query_frames"].get<int>());
  for (const auto& e : j["sessions"]) {
    append(&out, "session %s (%s): %lld frames, %lld keypoints, %lld with a landmark",
           e["name"].get<std::string>().c_str(), e["kind"].get<std::string>().c_str(), e["frames"].get<long long>(),
           e["keypoints"].get<long long>(), e["keypoints_with_landmark"].get<long long>());
    if (e.contains("landmarks_seen_only_here")) {
      append(&out, "; %lld landmarks seen by no other map session", e["landmarks_seen_only_here"].get<long long>());
    }
    append(&out, "\n");
  }
  append(&out, "keypoints: %lld map (%lld with a landmark), %lld query (%lld with a true landmark)\n",
         j["map_keypoints"].get<long long>(), j["map_keypoints_with_landmark"].get<long long>(),
         j["query_keypoints"].get<long long>(), j["query_keypoints_with_landmark"].get<long long>());
  append(&out, "landmarks: %lld (%lld with >= 5 and %lld with >= 10 map observations, %lld seen by queries)\n",
         j["landmarks"].get<long long>(), j["landmarks_with_5_map_observations"].get<long long>(),
         j["landmarks_with_10_map_observations"].get<long long>(), j["landmarks_seen_by_queries"].get<long long>());
  append(&out, "map observations per landmark: mean %.2f, median %d, max %d\n",
         j["map_observations_per_landmark"]["mean"].get<double>(),
         j["map_observations_per_landmark"]["median"].get<int>(), j["map_observations_per_landmark"]["max"].get<int>());
  append(&out, "mean reprojection error: %.3f px; quality %.3f .. %.3f\n",
         j["mean_reprojection_error_px"].get<double>(), j["quality"]["min"].get<double>(),
         j["quality"]["max"].get<double>());
  if (j.contains("reprojection_error_per_frame")) {
    out += frame_reprojection_text(j["reprojection_error_per_frame"]) + "\n";
  }
  if (j.contains("hamming_nn")) {
    const auto& nn = j["hamming_nn"];
    append(&out,
           "hamming NN precision@1: %.4f (%lld of %lld query keypoints; %lld map descriptors; "
           "mean NN distance %.1f bits, to true landmark %.1f bits)\n",
           nn["precision_at_1"].get<double>(), nn["correct"].get<long long>(), nn["queries"].get<long long>(),
           nn["database"].get<long long>(), nn["mean_nn_distance_bits"].get<double>(),
           nn["mean_true_landmark_distance_bits"].get<double>());
  }
  if (j.contains("depth_check")) {
    const auto& d = j["depth_check"];
    append(&out,
           "depth check (%lld landmarks): track purity %.4f (observations %.4f, pure tracks %.4f); "
           "position error median %.4f m, mean %.4f m, p90 %.4f m\n",
           d["landmarks_checked"].get<long long>(), d["mean_track_purity"].get<double>(),
           d["observation_purity"].get<double>(), d["pure_track_share"].get<double>(),
           d["median_position_error_m"].get<double>(), d["mean_position_error_m"].get<double>(),
           d["p90_position_error_m"].get<double>());
  }
  return out;
}

}  // namespace lmb
