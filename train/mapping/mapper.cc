#include "train/mapping/mapper.h"

#include "common/io/gravity_file.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <functional>
#include <map>
#include <mutex>
#include <thread>

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
  matching.check();
  triangulation.check();
  LMB_CHECK(min_map_observations >= 2,
            "mapper options: min_map_observations must be >= 2, got " << min_map_observations);
  LMB_CHECK(up.allFinite() && std::abs(up.norm() - 1.0) < 1e-9, "mapper options: up must be a unit vector");
  LMB_CHECK(threads >= 1 && threads <= 256, "mapper options: threads must be in 1..256, got " << threads);
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

// Pairs the frames, matches each pair (guided by the known poses) and joins the matches into
// tracks of map keypoints; counts them in *stats.
std::vector<std::vector<int64_t>> match_tracks(const std::vector<MapperFrame>& frames, const LandmarkMap& map,
                                               const std::vector<frame_t>& keypoint_frame, const MapperOptions& options,
                                               MapperStats* stats) {
  const std::vector<Camera>& cameras = map.cameras;
  const std::vector<MapSession>& sessions = map.sessions;
  const int num_frames = static_cast<int>(frames.size());
  const int descriptor_bytes = map.descriptor_bytes;
  std::vector<PairFrame> pair_frames;
  for (const MapperFrame& f : frames) {
    pair_frames.push_back(PairFrame{f.cam_from_world, f.is_query, f.session,
                                    sessions[static_cast<size_t>(f.session)].kind == SessionKind::kOutside});
  }
  const auto pairs = select_frame_pairs(pair_frames, options.pairs);
  stats->num_pairs = static_cast<int64_t>(pairs.size());
  std::vector<std::unique_ptr<MatchingFrame>> matching_frames(num_frames);
  parallel_for(num_frames, options.threads, [&](int64_t f, int) {
    matching_frames[f] =
        std::make_unique<MatchingFrame>(cameras[frames[f].camera], frames[f].cam_from_world, frames[f].keypoints,
                                        frames[f].descriptors.data(), descriptor_bytes);
  });
  std::vector<std::vector<Match>> pair_matches(pairs.size());
  {
    std::vector<GuidedMatcher> matchers(options.threads, GuidedMatcher(options.matching));
    parallel_for(static_cast<int64_t>(pairs.size()), options.threads, [&](int64_t p, int worker) {
      pair_matches[p] = matchers[worker].match(*matching_frames[pairs[p].first], *matching_frames[pairs[p].second]);
    });
  }
  std::vector<KeypointMatch> matches;
  for (size_t p = 0; p < pairs.size(); ++p) {
    const int64_t base_a = map.frames[pairs[p].first].first_keypoint;
    const int64_t base_b = map.frames[pairs[p].second].first_keypoint;
    for (const Match& m : pair_matches[p]) matches.push_back(KeypointMatch{base_a + m.a, base_b + m.b, m.distance});
  }
  stats->num_matches = static_cast<int64_t>(matches.size());
  pair_matches.clear();
  auto tracks = build_tracks(keypoint_frame, std::move(matches));
  stats->num_tracks = static_cast<int64_t>(tracks.size());
  return tracks;
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

  // Pairs and guided matching.
  const auto match_start = Clock::now();
  const std::vector<std::vector<int64_t>> tracks = match_tracks(frames, map, keypoint_frame, options, &stats);
  stats.match_seconds = seconds_since(match_start);

  // Triangulation.
  const auto triangulate_start = Clock::now();
  std::vector<TriangulatedPoint> points(tracks.size());
  parallel_for(static_cast<int64_t>(tracks.size()), options.threads, [&](int64_t t, int) {
    int map_observations = 0;
    std::vector<TrackObservation> obs;
    obs.reserve(tracks[t].size());
    for (int64_t k : tracks[t]) {
      const MapFrame& frame = map.frames[keypoint_frame[k]];
      map_observations += frame.is_query ? 0 : 1;
      obs.push_back(TrackObservation{&cameras[frame.camera], frame.cam_from_world,
                                     Eigen::Vector2d(map.keypoints[k].x, map.keypoints[k].y)});
    }
    if (map_observations < options.min_map_observations) return;  // cannot become a landmark
    points[t] = triangulate_track(obs, options.triangulation);
  });
  double error_sum = 0;
  for (size_t t = 0; t < tracks.size(); ++t) {
    const TriangulatedPoint& point = points[t];
    if (!point.success) continue;
    int num_map = 0, num_query = 0;
    for (size_t i = 0; i < tracks[t].size(); ++i) {
      if (!point.inlier[i]) continue;
      (map.frames[keypoint_frame[tracks[t][i]]].is_query ? num_query : num_map) += 1;
    }
    if (num_map < options.min_map_observations) continue;
    const landmark_t id = static_cast<landmark_t>(map.landmarks.size());
    for (size_t i = 0; i < tracks[t].size(); ++i) {
      if (point.inlier[i]) map.keypoint_landmark[tracks[t][i]] = id;
    }
    Landmark lm;
    lm.position = point.position;
    lm.mean_reprojection_error = static_cast<float>(point.mean_reprojection_error_px);
    lm.num_map_observations = num_map;
    lm.num_query_observations = num_query;
    lm.quality = landmark_quality(num_map, point.mean_reprojection_error_px, point.triangulation_angle_deg);
    map.landmarks.push_back(lm);
    stats.num_map_observations += num_map;
    stats.num_query_observations += num_query;
    error_sum += point.mean_reprojection_error_px;
  }
  stats.num_landmarks = static_cast<int64_t>(map.landmarks.size());
  if (stats.num_landmarks > 0) {
    stats.mean_map_observations = static_cast<double>(stats.num_map_observations) / stats.num_landmarks;
    stats.mean_reprojection_error_px = error_sum / stats.num_landmarks;
  }
  stats.triangulate_seconds = seconds_since(triangulate_start);
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
