#include "train/mapping/mapper.h"

#include "common/io/gravity_file.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <functional>
#include <iterator>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <tuple>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/io/colmap_model.h"
#include "common/io/session_file.h"
#include "train/mapping/tracks.h"

namespace lmb {

namespace fs = std::filesystem;

void MapperOptions::check() const {
  detector.check();
  pairs.check();
  overlap.check();
  matching.check();
  refinement.check();
  LMB_CHECK(track_splits >= 0, "mapper options: track_splits must be >= 0, got " << track_splits);
  LMB_CHECK(refine_inlier_factor >= 1 && refine_inlier_factor <= 10,
            "mapper options: refine_inlier_factor must be in [1, 10], got " << refine_inlier_factor);
  LMB_CHECK(refine_rounds >= 1 && refine_rounds <= 20,
            "mapper options: refine_rounds must be in 1..20, got " << refine_rounds);
  LMB_CHECK(auto_refine_min_change > 0 && auto_refine_min_change < 1,
            "mapper options: auto_refine_min_change must be in (0, 1), got " << auto_refine_min_change);
  LMB_CHECK(!refinement.principal_point || refine_focal != FocalRefinement::kOff,
            "mapper options: refining the principal point needs the focal refinement (auto or on)");
  triangulation.check();
  LMB_CHECK(min_map_observations >= 2,
            "mapper options: min_map_observations must be >= 2, got " << min_map_observations);
  LMB_CHECK(up.allFinite() && std::abs(up.norm() - 1.0) < 1e-9, "mapper options: up must be a unit vector");
  LMB_CHECK(threads >= 1 && threads <= 256, "mapper options: threads must be in 1..256, got " << threads);
}

std::string focal_refinement_name(FocalRefinement r) {
  switch (r) {
    case FocalRefinement::kOff: return "off";
    case FocalRefinement::kAuto: return "auto";
    case FocalRefinement::kOn: return "on";
  }
  return "?";
}

FocalRefinement parse_focal_refinement(const std::string& text) {
  for (FocalRefinement r : {FocalRefinement::kOff, FocalRefinement::kAuto, FocalRefinement::kOn}) {
    if (text == focal_refinement_name(r)) return r;
  }
  LMB_FAIL("--refine-focal: '" << text << "' is not auto, on or off");
}

Eigen::Vector3d parse_up_axis(const std::string& text) {
  std::string s = text;
  double sign = 1.0;
  if (!s.empty() && (s[0] == '+' || s[0] == '-')) {
    sign = s[0] == '-' ? -1.0 : 1.0;
    s = s.substr(1);
  }
  if (s == "x" || s == "X") return Eigen::Vector3d(sign, 0, 0);
  if (s == "y" || s == "Y") return Eigen::Vector3d(0, sign, 0);
  if (s == "z" || s == "Z") return Eigen::Vector3d(0, 0, sign);
  LMB_FAIL("--up: '" << text << "' is not an axis (expected +x, -x, +y, -y, +z or -z)");
}

float landmark_quality(int num_map_observations, double mean_reprojection_error_px, double triangulation_angle_deg) {
  return static_cast<float>(std::log1p(static_cast<double>(num_map_observations)) *
                            std::exp(-mean_reprojection_error_px / 2.0) *
                            (1.0 - std::exp(-triangulation_angle_deg / 10.0)));
}

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

// Runs body(i) for i in [0, n) on `threads` threads with dynamic scheduling. Results must be written
// by index, so they do not depend on the schedule. The exception of the smallest failing index is
// rethrown (deterministic error messages).
// body(i, worker) also gets the worker index in [0, threads) for per-thread scratch state.
void parallel_for(int64_t n, int threads, const std::function<void(int64_t, int)>& body) {
  if (threads <= 1 || n <= 1) {
    for (int64_t i = 0; i < n; ++i) body(i, 0);
    return;
  }
  std::atomic<int64_t> next{0};
  std::mutex mutex;
  int64_t failed_index = -1;
  std::exception_ptr failure;
  auto worker = [&](int worker_index) {
    while (true) {
      const int64_t i = next.fetch_add(1);
      if (i >= n) return;
      try {
        body(i, worker_index);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (failed_index < 0 || i < failed_index) {
          failed_index = i;
          failure = std::current_exception();
        }
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(worker, t);
  for (auto& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
}

// Copies the frames (keypoints, descriptors, gravity) into *map, whose cameras and sessions are
// set, checking each against them; counts the frames in *stats. Returns each keypoint's frame.
std::vector<frame_t> add_frames(const std::vector<MapperFrame>& frames, const MapperOptions& options, LandmarkMap* map,
                                MapperStats* stats) {
  const int descriptor_bytes = map->descriptor_bytes;
  std::vector<frame_t> keypoint_frame;
  const std::vector<Camera>& cameras = map->cameras;
  const std::vector<MapSession>& sessions = map->sessions;
  const int num_frames = static_cast<int>(frames.size());
  for (int f = 0; f < num_frames; ++f) {
    const MapperFrame& in = frames[f];
    LMB_CHECK(in.camera >= 0 && in.camera < static_cast<camera_t>(cameras.size()),
              "mapper: frame '" << in.name << "': camera index " << in.camera << " out of range");
    LMB_CHECK(in.session >= 0 && in.session < static_cast<int32_t>(sessions.size()),
              "mapper: frame '" << in.name << "': session index " << in.session << " out of range");
    const SessionKind kind = sessions[static_cast<size_t>(in.session)].kind;
    LMB_CHECK(in.is_query == (kind != SessionKind::kMap),
              "mapper: frame '" << in.name << "': is_query " << in.is_query << " in the " << session_kind_name(kind)
                                << " session '" << sessions[static_cast<size_t>(in.session)].name << "'");
    LMB_CHECK(in.descriptors.size() == in.keypoints.size() * static_cast<size_t>(descriptor_bytes),
              "mapper: frame '" << in.name << "': descriptor rows do not match the keypoints");
    MapFrame out;
    out.name = in.name;
    out.camera = in.camera;
    out.session = in.session;
    out.cam_from_world = in.cam_from_world;
    out.gravity_in_cam =
        in.gravity_in_cam ? in.gravity_in_cam->normalized() : (in.cam_from_world.rotation * (-options.up)).normalized();
    out.is_query = in.is_query;
    out.first_keypoint = static_cast<int64_t>(map->keypoints.size());
    out.num_keypoints = static_cast<int32_t>(in.keypoints.size());
    map->frames.push_back(out);
    map->keypoints.insert(map->keypoints.end(), in.keypoints.begin(), in.keypoints.end());
    map->descriptors.insert(map->descriptors.end(), in.descriptors.begin(), in.descriptors.end());
    keypoint_frame.insert(keypoint_frame.end(), in.keypoints.size(), f);
    (in.is_query ? stats->num_query_frames : stats->num_map_frames) += 1;
    stats->num_outside_frames += kind == SessionKind::kOutside;
  }
  return keypoint_frame;
}

// The frames prepared for guided matching with the given cameras.
std::vector<std::unique_ptr<MatchingFrame>> prepare_matching_frames(const std::vector<MapperFrame>& frames,
                                                                    const std::vector<Camera>& cameras,
                                                                    int descriptor_bytes, int threads) {
  std::vector<std::unique_ptr<MatchingFrame>> out(frames.size());
  parallel_for(static_cast<int64_t>(frames.size()), threads, [&](int64_t f, int) {
    out[f] = std::make_unique<MatchingFrame>(cameras[frames[f].camera], frames[f].cam_from_world, frames[f].keypoints,
                                             frames[f].descriptors.data(), descriptor_bytes);
  });
  return out;
}

// Mutual guided matches of every pair, appended to *matches as global keypoint indices.
void match_pairs(const std::vector<std::pair<int, int>>& pairs,
                 const std::vector<std::unique_ptr<MatchingFrame>>& matching_frames, const LandmarkMap& map,
                 const MapperOptions& options, std::vector<KeypointMatch>* matches) {
  std::vector<std::vector<Match>> pair_matches(pairs.size());
  std::vector<GuidedMatcher> matchers(options.threads, GuidedMatcher(options.matching));
  parallel_for(static_cast<int64_t>(pairs.size()), options.threads, [&](int64_t p, int worker) {
    pair_matches[p] = matchers[worker].match(*matching_frames[pairs[p].first], *matching_frames[pairs[p].second]);
  });
  for (size_t p = 0; p < pairs.size(); ++p) {
    const int64_t base_a = map.frames[pairs[p].first].first_keypoint;
    const int64_t base_b = map.frames[pairs[p].second].first_keypoint;
    for (const Match& m : pair_matches[p]) matches->push_back(KeypointMatch{base_a + m.a, base_b + m.b, m.distance});
  }
}

// The tracks and their triangulated points: what matching and triangulation give for one set of
// cameras.
struct TrackSet {
  std::vector<std::vector<int64_t>> matched;  // the tracks joined from the matches
  std::vector<std::vector<int64_t>> tracks;   // after triangulation: the matched tracks, split
  std::vector<TriangulatedPoint> points;      // per (sub)track
};

// A point split off a track lies at least this far (relative to its mean distance from the cameras
// that see it) from the points split before it; nearer, it is taken for the same point seen
// through noisy poses and stays without a landmark (its observations are background).
constexpr double kMinSplitSeparation = 0.02;

// Triangulates a track with enough map keypoints; the outliers of a triangulated track (two points
// joined by a wrong match, e.g. repeated structure) are triangulated again as a track of their own,
// up to options.track_splits times. Appends each (sub)track and its point to *out; a track too
// short to become a landmark is appended untriangulated.
void triangulate_and_split(const std::vector<int64_t>& track, const LandmarkMap& map,
                           const std::vector<frame_t>& keypoint_frame, const MapperOptions& options, TrackSet* out) {
  std::vector<int64_t> rest = track;
  static const int dbg_splits =
      std::getenv("LMB_DEBUG_SPLITS") ? std::atoi(std::getenv("LMB_DEBUG_SPLITS")) : options.track_splits;  // DEBUG
  static const double dbg_sep =
      std::getenv("LMB_DEBUG_SPLITSEP") ? std::atof(std::getenv("LMB_DEBUG_SPLITSEP")) : kMinSplitSeparation;  // DEBUG
  for (int split = 0; split <= dbg_splits && rest.size() >= 2; ++split) {
    int map_observations = 0;
    std::vector<TrackObservation> obs;
    obs.reserve(rest.size());
    for (int64_t k : rest) {
      const MapFrame& frame = map.frames[keypoint_frame[k]];
      map_observations += frame.is_query ? 0 : 1;
      obs.push_back(TrackObservation{&map.cameras[frame.camera], frame.cam_from_world,
                                     Eigen::Vector2d(map.keypoints[k].x, map.keypoints[k].y)});
    }
    if (map_observations < options.min_map_observations) break;  // cannot become a landmark
    TriangulatedPoint point = triangulate_track(obs, options.triangulation);
    if (!point.success) break;
    // A distinct point: the points split before it reproject far from its observations.
    for (const TriangulatedPoint& before : out->points) {
      std::vector<double> errors;
      for (size_t i = 0; i < rest.size(); ++i) {
        if (point.inlier[i]) errors.push_back(reprojection_error_px(obs[i], before.position));
      }
      std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
      if (errors[errors.size() / 2] < dbg_sep * options.triangulation.max_reprojection_error_px) point.success = false;
    }
    std::vector<int64_t> outliers;
    for (size_t i = 0; i < rest.size(); ++i) {
      if (!point.inlier[i]) outliers.push_back(rest[i]);
    }
    out->tracks.push_back(std::move(rest));
    out->points.push_back(std::move(point));
    rest = std::move(outliers);
  }
  if (out->tracks.empty() || rest.size() >= 2) {
    out->tracks.push_back(std::move(rest));
    out->points.emplace_back();
  }
}

// triangulate_and_split on every track, with the map's cameras and poses; (sub)tracks in track order.
TrackSet triangulate_tracks(const std::vector<std::vector<int64_t>>& tracks, const LandmarkMap& map,
                            const std::vector<frame_t>& keypoint_frame, const MapperOptions& options) {
  std::vector<TrackSet> parts(tracks.size());
  parallel_for(static_cast<int64_t>(tracks.size()), options.threads,
               [&](int64_t t, int) { triangulate_and_split(tracks[t], map, keypoint_frame, options, &parts[t]); });
  TrackSet set;
  for (TrackSet& part : parts) {
    for (size_t i = 0; i < part.tracks.size(); ++i) {
      set.tracks.push_back(std::move(part.tracks[i]));
      set.points.push_back(std::move(part.points[i]));
    }
  }
  return set;
}

// A track's inlier observations in map and query frames; a landmark when num_map is large enough.
struct InlierCounts {
  int num_map = 0, num_query = 0;
};
InlierCounts count_inliers(const std::vector<int64_t>& track, const TriangulatedPoint& point, const LandmarkMap& map,
                           const std::vector<frame_t>& keypoint_frame) {
  InlierCounts c;
  if (!point.success) return c;
  for (size_t i = 0; i < track.size(); ++i) {
    if (point.inlier[i]) (map.frames[keypoint_frame[track[i]]].is_query ? c.num_query : c.num_map) += 1;
  }
  return c;
}

TrackSet tracks_from_matches(std::vector<KeypointMatch> matches, const LandmarkMap& map,
                             const std::vector<frame_t>& keypoint_frame, const MapperOptions& options,
                             int64_t* num_tracks, double* triangulate_seconds) {
  std::vector<std::vector<int64_t>> tracks = build_tracks(keypoint_frame, std::move(matches));
  *num_tracks = static_cast<int64_t>(tracks.size());
  const auto start = Clock::now();
  TrackSet set = triangulate_tracks(tracks, map, keypoint_frame, options);
  set.matched = std::move(tracks);
  *triangulate_seconds += seconds_since(start);
  return set;
}

// The first map's scene points (the landmarks the tracks would give) and the map frames seeing each.
ScenePoints scene_points(const TrackSet& set, const LandmarkMap& map, const std::vector<frame_t>& keypoint_frame,
                         int min_map_observations) {
  ScenePoints scene;
  for (size_t t = 0; t < set.tracks.size(); ++t) {
    if (count_inliers(set.tracks[t], set.points[t], map, keypoint_frame).num_map < min_map_observations) continue;
    std::vector<int> observers;
    for (size_t i = 0; i < set.tracks[t].size(); ++i) {
      const frame_t f = keypoint_frame[set.tracks[t][i]];
      if (set.points[t].inlier[i] && !map.frames[f].is_query) observers.push_back(f);
    }
    std::sort(observers.begin(), observers.end());
    observers.erase(std::unique(observers.begin(), observers.end()), observers.end());
    scene.position.push_back(set.points[t].position);
    scene.observers.push_back(std::move(observers));
  }
  return scene;
}

// Chooses the frame pairs and matches them: the pose rule (select_frame_pairs) for every frame;
// without an explicit pair distance (and with query frames), it is matched among map frames first,
// a first map is made from those matches, and the overlap rule on its points adds the query
// frames' partners (select_overlap_pairs) to their pose-rule pairs. Returns the pairs (sorted);
// their matches go to *matches.
std::vector<std::pair<int, int>> choose_and_match_pairs(
    const std::vector<MapperFrame>& frames, const LandmarkMap& map, const std::vector<frame_t>& keypoint_frame,
    const std::vector<std::unique_ptr<MatchingFrame>>& matching_frames, const MapperOptions& options,
    std::vector<KeypointMatch>* matches, MapperStats* stats) {
  std::vector<PairFrame> pair_frames;
  for (const MapperFrame& f : frames) {
    pair_frames.push_back(PairFrame{f.cam_from_world, f.is_query, f.session,
                                    map.sessions[static_cast<size_t>(f.session)].kind == SessionKind::kOutside,
                                    &map.cameras[f.camera]});
  }
  const auto by_pose = select_frame_pairs(pair_frames, options.pairs);
  const bool any_query =
      std::any_of(pair_frames.begin(), pair_frames.end(), [](const PairFrame& f) { return f.is_query && !f.outside; });
  if (options.pairs.max_center_distance > 0 || !any_query) {
    match_pairs(by_pose, matching_frames, map, options, matches);
    return by_pose;
  }
  // First pass: map-frame pairs by pose; their tracks give the scene points.
  std::vector<std::pair<int, int>> first_pass, query_by_pose;
  for (const auto& pair : by_pose) {
    (frames[pair.first].is_query || frames[pair.second].is_query ? query_by_pose : first_pass).push_back(pair);
  }
  match_pairs(first_pass, matching_frames, map, options, matches);
  int64_t first_pass_tracks = 0;
  double seconds = 0;
  const TrackSet first_map = tracks_from_matches(*matches, map, keypoint_frame, options, &first_pass_tracks, &seconds);
  const ScenePoints scene = scene_points(first_map, map, keypoint_frame, options.min_map_observations);
  OverlapPairOptions overlap = options.overlap;
  overlap.min_depth = options.matching.min_depth;
  overlap.max_depth = options.matching.max_depth;
  const auto by_overlap = select_overlap_pairs(pair_frames, scene, overlap, &stats->overlap);
  std::vector<std::pair<int, int>> query_pairs;
  std::set_union(query_by_pose.begin(), query_by_pose.end(), by_overlap.begin(), by_overlap.end(),
                 std::back_inserter(query_pairs));
  match_pairs(query_pairs, matching_frames, map, options, matches);
  stats->pairs_by_overlap = true;
  stats->num_first_pass_pairs = static_cast<int64_t>(first_pass.size());
  stats->num_first_pass_points = static_cast<int64_t>(scene.position.size());
  stats->num_query_pose_pairs = static_cast<int64_t>(query_by_pose.size());
  std::vector<std::pair<int, int>> pairs;
  std::set_union(first_pass.begin(), first_pass.end(), query_pairs.begin(), query_pairs.end(),
                 std::back_inserter(pairs));
  return pairs;
}

// Mean reprojection error over the tracks that become landmarks, and their count.
std::pair<double, int64_t> landmark_error(const TrackSet& set, const LandmarkMap& map,
                                          const std::vector<frame_t>& keypoint_frame, int min_map_observations,
                                          int64_t* query_observations) {
  double sum = 0;
  int64_t count = 0;
  *query_observations = 0;
  for (size_t t = 0; t < set.tracks.size(); ++t) {
    const InlierCounts c = count_inliers(set.tracks[t], set.points[t], map, keypoint_frame);
    if (c.num_map < min_map_observations) continue;
    sum += set.points[t].mean_reprojection_error_px;
    *query_observations += c.num_query;
    ++count;
  }
  return {count > 0 ? sum / static_cast<double>(count) : 0.0, count};
}

// The landmark tracks of `set` (inlier observations) as the camera refinement takes them.
std::vector<RefinementTrack> refinement_tracks(const TrackSet& set, const LandmarkMap& map,
                                               const std::vector<frame_t>& keypoint_frame, int min_map_observations) {
  std::vector<RefinementTrack> tracks;
  for (size_t t = 0; t < set.tracks.size(); ++t) {
    if (count_inliers(set.tracks[t], set.points[t], map, keypoint_frame).num_map < min_map_observations) continue;
    RefinementTrack r;
    r.position = set.points[t].position;
    for (size_t i = 0; i < set.tracks[t].size(); ++i) {
      if (!set.points[t].inlier[i]) continue;
      const int64_t k = set.tracks[t][i];
      r.frames.push_back(keypoint_frame[k]);
      r.pixels.emplace_back(map.keypoints[k].x, map.keypoints[k].y);
    }
    tracks.push_back(std::move(r));
  }
  return tracks;
}

// The frames' poses and cameras, as refine_cameras takes them.
void frame_poses(const LandmarkMap& map, std::vector<Rigid3d>* poses, std::vector<camera_t>* frame_camera) {
  for (const MapFrame& f : map.frames) {
    poses->push_back(f.cam_from_world);
    frame_camera->push_back(f.camera);
  }
}

// The largest relative change of a camera's mean focal length from `a` to `b`.
double largest_focal_change(const std::vector<Camera>& a, const std::vector<Camera>& b) {
  double change = 0;
  for (size_t c = 0; c < a.size(); ++c) {
    change = std::max(change, std::abs(b[c].mean_focal_length() / a[c].mean_focal_length() - 1.0));
  }
  return change;
}

// Triangulates set->matched again with the map's cameras into *set.
void retriangulate(const LandmarkMap& map, const std::vector<frame_t>& keypoint_frame, const MapperOptions& options,
                   TrackSet* set) {
  std::vector<std::vector<int64_t>> matched = std::move(set->matched);
  *set = triangulate_tracks(matched, map, keypoint_frame, options);
  set->matched = std::move(matched);
}

// Alternates camera refinement on the landmark tracks and triangulation of the matched tracks
// with the refined cameras until no focal length moves by 0.1% (at most 20 times), then
// triangulates with the final cameras. While refining, an observation is an inlier up to
// refine_inlier_factor x the triangulation threshold: the observations that a wrong focal length
// pushes out of the usual threshold (far from the image centre, wide baselines) are the ones that
// tell the right one. Returns the largest relative focal change from the cameras on entry.
double refine_and_triangulate(const MapperOptions& options, const std::vector<frame_t>& keypoint_frame,
                              LandmarkMap* map, TrackSet* set) {
  std::vector<Rigid3d> poses;
  std::vector<camera_t> frame_camera;
  frame_poses(*map, &poses, &frame_camera);
  const std::vector<Camera> entry = map->cameras;
  MapperOptions wide = options;
  wide.triangulation.max_reprojection_error_px *= options.refine_inlier_factor;
  retriangulate(*map, keypoint_frame, wide, set);
  for (int step = 0; step < 20; ++step) {
    const CameraRefinementResult refined =
        refine_cameras(map->cameras, poses, frame_camera,
                       refinement_tracks(*set, *map, keypoint_frame, options.min_map_observations), options.refinement);
    const double change = largest_focal_change(map->cameras, refined.cameras);
    map->cameras = refined.cameras;
    if (change < 1e-3) break;
    retriangulate(*map, keypoint_frame, wide, set);
  }
  retriangulate(*map, keypoint_frame, options, set);
  return largest_focal_change(entry, map->cameras);
}

// The focal check (refine_focal kAuto or kOff): one refinement of the cameras on the landmark tracks of
// `set` triangulated with the refinement's wide inlier threshold; the map keeps its cameras.
void check_focal(const MapperOptions& options, const std::vector<frame_t>& keypoint_frame, const LandmarkMap& map,
                 const TrackSet& set, MapperStats* stats) {
  std::vector<Rigid3d> poses;
  std::vector<camera_t> frame_camera;
  frame_poses(map, &poses, &frame_camera);
  MapperOptions wide = options;
  wide.triangulation.max_reprojection_error_px *= options.refine_inlier_factor;
  TrackSet wide_set;
  wide_set.matched = set.matched;
  retriangulate(map, keypoint_frame, wide, &wide_set);
  const CameraRefinementResult r = refine_cameras(
      map.cameras, poses, frame_camera, refinement_tracks(wide_set, map, keypoint_frame, options.min_map_observations),
      options.refinement);
  stats->focal_check.clear();
  for (size_t c = 0; c < map.cameras.size(); ++c) {
    stats->focal_check.push_back(FocalCheck{map.cameras[c].mean_focal_length(), r.cameras[c].mean_focal_length(),
                                            r.mean_error_before_px[c], r.mean_error_after_px[c], r.observations[c]});
  }
}

// Whether the focal check moved a camera's focal length by more than min_change (relative).
bool focal_check_moved(const MapperStats& stats, double min_change) {
  for (const FocalCheck& f : stats.focal_check) {
    if (std::abs(f.fitted_focal_px / f.focal_px - 1.0) > min_change) return true;
  }
  return false;
}

// Refines the map's cameras on the landmark tracks of *set (refine_and_triangulate), then matches
// the pairs again with them while they moved by more than 0.1%, up to options.refine_rounds
// rounds; *set and map->cameras hold the result.
void refine_cameras_and_remap(const std::vector<MapperFrame>& frames, const std::vector<std::pair<int, int>>& pairs,
                              const std::vector<frame_t>& keypoint_frame, const MapperOptions& options,
                              LandmarkMap* map, TrackSet* set, MapperStats* stats) {
  stats->cameras_before = map->cameras;
  std::tie(stats->reprojection_error_before_px, stats->landmarks_before) =
      landmark_error(*set, *map, keypoint_frame, options.min_map_observations, &stats->query_observations_before);
  for (int round = 0; round < options.refine_rounds; ++round) {
    const double moved = refine_and_triangulate(options, keypoint_frame, map, set);
    stats->refine_rounds = round + 1;
    if (moved < 1e-3) break;  // the matches were made with (nearly) these cameras
    const auto matching_frames = prepare_matching_frames(frames, map->cameras, map->descriptor_bytes, options.threads);
    std::vector<KeypointMatch> matches;
    match_pairs(pairs, matching_frames, *map, options, &matches);
    stats->num_matches = static_cast<int64_t>(matches.size());
    double seconds = 0;  // counted in refine_seconds
    *set = tracks_from_matches(std::move(matches), *map, keypoint_frame, options, &stats->num_tracks, &seconds);
  }
  stats->cameras_after = map->cameras;
}

// Turns the triangulated tracks with enough map inliers into the map's landmarks.
void add_landmarks(const TrackSet& set, const std::vector<frame_t>& keypoint_frame, const MapperOptions& options,
                   LandmarkMap* map, MapperStats* stats) {
  double error_sum = 0;
  for (size_t t = 0; t < set.tracks.size(); ++t) {
    const TriangulatedPoint& point = set.points[t];
    const InlierCounts c = count_inliers(set.tracks[t], point, *map, keypoint_frame);
    if (c.num_map < options.min_map_observations) continue;
    const landmark_t id = static_cast<landmark_t>(map->landmarks.size());
    for (size_t i = 0; i < set.tracks[t].size(); ++i) {
      if (point.inlier[i]) map->keypoint_landmark[set.tracks[t][i]] = id;
    }
    Landmark lm;
    lm.position = point.position;
    lm.mean_reprojection_error = static_cast<float>(point.mean_reprojection_error_px);
    lm.num_map_observations = c.num_map;
    lm.num_query_observations = c.num_query;
    lm.quality = landmark_quality(c.num_map, point.mean_reprojection_error_px, point.triangulation_angle_deg);
    map->landmarks.push_back(lm);
    stats->num_map_observations += c.num_map;
    stats->num_query_observations += c.num_query;
    error_sum += point.mean_reprojection_error_px;
  }
  stats->num_landmarks = static_cast<int64_t>(map->landmarks.size());
  if (stats->num_landmarks > 0) {
    stats->mean_map_observations = static_cast<double>(stats->num_map_observations) / stats->num_landmarks;
    stats->mean_reprojection_error_px = error_sum / stats->num_landmarks;
  }
}

}  // namespace

LandmarkMap build_landmark_map(const std::vector<Camera>& cameras, const std::vector<MapperFrame>& frames,
                               const std::string& detector, int descriptor_bytes, const MapperOptions& options,
                               MapperStats* stats_out) {
  LandmarkMap by_flag;
  for (const MapperFrame& f : frames) {
    MapFrame mf;
    mf.is_query = f.is_query;
    by_flag.frames.push_back(mf);
  }
  assign_sessions_from_query_flags(&by_flag);
  std::vector<MapperFrame> with_sessions = frames;
  for (size_t f = 0; f < frames.size(); ++f) with_sessions[f].session = by_flag.frames[f].session;
  return build_landmark_map(cameras, by_flag.sessions, with_sessions, detector, descriptor_bytes, options, stats_out);
}

LandmarkMap build_landmark_map(const std::vector<Camera>& cameras, const std::vector<MapSession>& sessions,
                               const std::vector<MapperFrame>& frames, const std::string& detector,
                               int descriptor_bytes, const MapperOptions& options, MapperStats* stats_out) {
  options.check();
  const auto start = Clock::now();
  MapperStats stats;
  LMB_CHECK(descriptor_bytes > 0, "mapper: descriptor_bytes must be positive");
  const int num_frames = static_cast<int>(frames.size());
  LMB_CHECK(num_frames == 0 || !sessions.empty(), "mapper: " << num_frames << " frames but no session");
  for (size_t s = 0; s < sessions.size(); ++s) {
    LMB_CHECK(!sessions[s].name.empty() && sessions[s].name.find_first_of(" \t\r\n") == std::string::npos,
              "mapper: session " << s << ": name '" << sessions[s].name << "' is empty or contains white space");
    for (size_t t = 0; t < s; ++t) {
      LMB_CHECK(sessions[t].name != sessions[s].name, "mapper: two sessions are called '" << sessions[s].name << "'");
    }
  }
  stats.num_sessions = static_cast<int>(sessions.size());

  LandmarkMap map;
  map.detector = detector;
  map.descriptor_bytes = descriptor_bytes;
  map.cameras = cameras;
  map.sessions = sessions;
  const std::vector<frame_t> keypoint_frame = add_frames(frames, options, &map, &stats);
  const int64_t num_keypoints = static_cast<int64_t>(map.keypoints.size());
  map.keypoint_landmark.assign(num_keypoints, kInvalidLandmarkId);
  stats.num_keypoints = num_keypoints;

  // Pairs and guided matching; tracks and triangulation.
  const auto match_start = Clock::now();
  std::vector<KeypointMatch> matches;
  const std::vector<std::pair<int, int>> pairs = choose_and_match_pairs(
      frames, map, keypoint_frame, prepare_matching_frames(frames, map.cameras, descriptor_bytes, options.threads),
      options, &matches, &stats);
  stats.num_pairs = static_cast<int64_t>(pairs.size());
  stats.num_matches = static_cast<int64_t>(matches.size());
  stats.match_seconds = seconds_since(match_start);
  TrackSet set = tracks_from_matches(std::move(matches), map, keypoint_frame, options, &stats.num_tracks,
                                     &stats.triangulate_seconds);
  const auto refine_start = Clock::now();
  if (options.refine_focal != FocalRefinement::kOn) check_focal(options, keypoint_frame, map, set, &stats);
  if (options.refine_focal == FocalRefinement::kOn ||
      (options.refine_focal == FocalRefinement::kAuto && focal_check_moved(stats, options.auto_refine_min_change))) {
    refine_cameras_and_remap(frames, pairs, keypoint_frame, options, &map, &set, &stats);
    stats.refined = true;
  }
  stats.refine_seconds = seconds_since(refine_start);
  add_landmarks(set, keypoint_frame, options, &map, &stats);
  stats.reprojection_error_after_px = stats.mean_reprojection_error_px;
  stats.total_seconds = seconds_since(start);
  if (stats_out) {
    const double detect = stats_out->detect_seconds;
    *stats_out = stats;
    stats_out->detect_seconds = detect;
  }
  return map;
}

namespace {

// One collection read for mapping: its cameras, sessions and frames (features not yet detected),
// with the image paths.
struct LoadedCollection {
  std::vector<Camera> cameras;
  std::vector<MapSession> sessions;
  std::vector<MapperFrame> frames;  // camera and session index into the above
  std::vector<fs::path> image_paths;
};

LoadedCollection load_collection(const fs::path& collection_dir, const fs::path& gravity_file,
                                 const MapperOptions& options) {
  const fs::path sparse = collection_dir / "sparse";
  const fs::path image_dir = collection_dir / "images";
  LMB_CHECK(fs::is_directory(collection_dir), collection_dir.string() << ": collection folder does not exist");
  LMB_CHECK(fs::is_directory(sparse), sparse.string() << ": missing sparse model folder");
  LMB_CHECK(fs::is_directory(image_dir), image_dir.string() << ": missing image folder");
  ColmapModel model;
  try {
    model = read_colmap_model(sparse);
  } catch (const Error& e) {
    // Errors that do not name their file yet (e.g. an unknown camera model) get the folder.
    const std::string message = e.what();
    if (message.find(sparse.string()) != std::string::npos) throw;
    LMB_FAIL(sparse.string() << ": " << message);
  }
  LMB_CHECK(!model.images.empty(), sparse.string() << ": the sparse model has no images");
  check_collection_images(model, image_dir);
  std::map<std::string, Eigen::Vector3d> gravity;
  if (!gravity_file.empty()) gravity = read_gravity_file(gravity_file, model);

  LoadedCollection c;
  std::vector<int32_t> session_of_image;
  const fs::path session_file = collection_dir / kSessionFileName;
  if (fs::exists(session_file)) {
    c.sessions = read_session_file(session_file);
    session_of_image = image_sessions(c.sessions, model, session_file);
  } else {
    c.sessions = {MapSession{"map", SessionKind::kMap}};
    bool any_query = false;
    for (const ColmapImage& image : model.images) {
      const bool query = !options.query_prefix.empty() && image.name.rfind(options.query_prefix, 0) == 0;
      session_of_image.push_back(query ? 1 : 0);
      any_query = any_query || query;
    }
    if (any_query) c.sessions.push_back(MapSession{"query", SessionKind::kQuery});
  }
  std::map<int, camera_t> camera_index;
  for (const auto& [id, camera] : model.cameras) {
    camera_index[id] = static_cast<camera_t>(c.cameras.size());
    c.cameras.push_back(camera);
  }
  c.frames.resize(model.images.size());
  for (size_t i = 0; i < model.images.size(); ++i) {
    const ColmapImage& image = model.images[i];
    MapperFrame& f = c.frames[i];
    f.name = image.name;
    f.camera = camera_index.at(image.camera_id);
    f.session = session_of_image[i];
    f.cam_from_world = image.cam_from_world;
    f.is_query = c.sessions[static_cast<size_t>(f.session)].kind != SessionKind::kMap;
    if (!gravity.empty()) f.gravity_in_cam = gravity.at(image.name);
    c.image_paths.push_back(image_dir / image.name);
  }
  return c;
}

}  // namespace

LandmarkMap map_collections(const std::vector<CollectionInput>& collections, const MapperOptions& options,
                            MapperStats* stats_out) {
  options.check();
  LMB_CHECK(!collections.empty(), "mapper: no collection to map");
  const auto start = Clock::now();
  const bool joined = collections.size() > 1;
  std::vector<std::string> labels;
  for (const CollectionInput& in : collections) {
    std::string label = in.label;
    if (label.empty()) label = fs::path(in.dir).lexically_normal().filename().string();
    if (label.empty() || label == ".")
      label = fs::absolute(in.dir).lexically_normal().parent_path().filename().string();
    if (joined) {
      check_session_name(label, "mapper: collection " + in.dir.string() + ": label");
      for (size_t k = 0; k < labels.size(); ++k) {
        LMB_CHECK(labels[k] != label, "mapper: collections " << collections[k].dir.string() << " and "
                                                             << in.dir.string() << " both have the label '" << label
                                                             << "' (give each its own label)");
      }
    }
    labels.push_back(label);
  }

  std::vector<Camera> cameras;
  std::vector<MapSession> sessions;
  std::vector<MapperFrame> frames;
  std::vector<fs::path> image_paths;
  for (size_t k = 0; k < collections.size(); ++k) {
    LoadedCollection c = load_collection(collections[k].dir, collections[k].gravity_file, options);
    const camera_t camera_base = static_cast<camera_t>(cameras.size());
    const int32_t session_base = static_cast<int32_t>(sessions.size());
    const std::string prefix = joined ? labels[k] + "/" : "";
    cameras.insert(cameras.end(), c.cameras.begin(), c.cameras.end());
    for (MapSession s : c.sessions) {
      s.name = prefix + s.name;
      sessions.push_back(std::move(s));
    }
    for (MapperFrame& f : c.frames) {
      f.name = prefix + f.name;
      f.camera += camera_base;
      f.session += session_base;
      frames.push_back(std::move(f));
    }
    image_paths.insert(image_paths.end(), c.image_paths.begin(), c.image_paths.end());
  }

  const int previous_cv_threads = cv::getNumThreads();
  cv::setNumThreads(1);  // parallelism comes from our own threads
  MapperStats stats;
  try {
    parallel_for(static_cast<int64_t>(frames.size()), options.threads, [&](int64_t i, int) {
      MapperFrame& f = frames[i];
      const fs::path& path = image_paths[i];
      const cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
      LMB_CHECK(!image.empty(), path.string() << ": cannot read image (unreadable or not an image)");
      const Camera& camera = cameras[f.camera];
      LMB_CHECK(image.cols == camera.width && image.rows == camera.height,
                path.string() << ": image is " << image.cols << "x" << image.rows << " but its camera is "
                              << camera.width << "x" << camera.height);
      options.detector.check_image_size(image.cols, image.rows, path.string());
      ImageFeatures features = detect_keypoints(image, options.detector);
      f.keypoints = std::move(features.keypoints);
      f.descriptors = std::move(features.descriptors);
    });
  } catch (...) {
    cv::setNumThreads(previous_cv_threads);
    throw;
  }
  cv::setNumThreads(previous_cv_threads);
  stats.detect_seconds = seconds_since(start);
  LandmarkMap map = build_landmark_map(cameras, sessions, frames, options.detector.detector,
                                       detector_descriptor_bytes(options.detector.detector), options, &stats);
  stats.total_seconds = seconds_since(start);
  if (stats_out) *stats_out = stats;
  return map;
}

LandmarkMap map_collection(const fs::path& collection_dir, const MapperOptions& options, MapperStats* stats_out) {
  return map_collections({CollectionInput{collection_dir, "", options.gravity_file}}, options, stats_out);
}

}  // namespace lmb
