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
#include "train/mapping/tracks.h"

namespace lmb {

namespace fs = std::filesystem;

void MapperOptions::check() const {
  detector.check();
  pairs.check();
  matching.check();
  triangulation.check();
  LMB_CHECK(min_map_observations >= 2, "mapper options: min_map_observations must be >= 2, got "
                                           << min_map_observations);
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

float landmark_quality(int num_map_observations, double mean_reprojection_error_px,
                       double triangulation_angle_deg) {
  return static_cast<float>(std::log1p(static_cast<double>(num_map_observations)) *
                            std::exp(-mean_reprojection_error_px / 2.0) *
                            (1.0 - std::exp(-triangulation_angle_deg / 10.0)));
}

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

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

}  // namespace

LandmarkMap build_landmark_map(const std::vector<Camera>& cameras, const std::vector<MapperFrame>& frames,
                               const std::string& detector, int descriptor_bytes, const MapperOptions& options,
                               MapperStats* stats_out) {
  options.check();
  const auto start = Clock::now();
  MapperStats stats;
  LMB_CHECK(descriptor_bytes > 0, "mapper: descriptor_bytes must be positive");
  const int num_frames = static_cast<int>(frames.size());

  LandmarkMap map;
  map.detector = detector;
  map.descriptor_bytes = descriptor_bytes;
  map.cameras = cameras;
  std::vector<frame_t> keypoint_frame;
  for (int f = 0; f < num_frames; ++f) {
    const MapperFrame& in = frames[f];
    LMB_CHECK(in.camera >= 0 && in.camera < static_cast<camera_t>(cameras.size()),
              "mapper: frame '" << in.name << "': camera index " << in.camera << " out of range");
    LMB_CHECK(in.descriptors.size() == in.keypoints.size() * static_cast<size_t>(descriptor_bytes),
              "mapper: frame '" << in.name << "': descriptor rows do not match the keypoints");
    MapFrame out;
    out.name = in.name;
    out.camera = in.camera;
    out.cam_from_world = in.cam_from_world;
    out.gravity_in_cam = in.gravity_in_cam ? in.gravity_in_cam->normalized()
                                         : (in.cam_from_world.rotation * (-options.up)).normalized();
    out.is_query = in.is_query;
    out.first_keypoint = static_cast<int64_t>(map.keypoints.size());
    out.num_keypoints = static_cast<int32_t>(in.keypoints.size());
    map.frames.push_back(out);
    map.keypoints.insert(map.keypoints.end(), in.keypoints.begin(), in.keypoints.end());
    map.descriptors.insert(map.descriptors.end(), in.descriptors.begin(), in.descriptors.end());
    keypoint_frame.insert(keypoint_frame.end(), in.keypoints.size(), f);
    (in.is_query ? stats.num_query_frames : stats.num_map_frames) += 1;
  }
  const int64_t num_keypoints = static_cast<int64_t>(map.keypoints.size());
  map.keypoint_landmark.assign(num_keypoints, kInvalidLandmarkId);
  stats.num_keypoints = num_keypoints;

  // Pairs and guided matching.
  const auto match_start = Clock::now();
  std::vector<PairFrame> pair_frames;
  for (const MapperFrame& f : frames) pair_frames.push_back(PairFrame{f.cam_from_world, f.is_query});
  const auto pairs = select_frame_pairs(pair_frames, options.pairs);
  stats.num_pairs = static_cast<int64_t>(pairs.size());
  std::vector<std::unique_ptr<MatchingFrame>> matching_frames(num_frames);
  parallel_for(num_frames, options.threads, [&](int64_t f, int) {
    matching_frames[f] = std::make_unique<MatchingFrame>(cameras[frames[f].camera], frames[f].cam_from_world,
                                                         frames[f].keypoints, frames[f].descriptors.data(),
                                                         descriptor_bytes);
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
  stats.num_matches = static_cast<int64_t>(matches.size());
  pair_matches.clear();
  const auto tracks = build_tracks(keypoint_frame, std::move(matches));
  stats.num_tracks = static_cast<int64_t>(tracks.size());
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

LandmarkMap map_collection(const fs::path& collection_dir, const MapperOptions& options, MapperStats* stats_out) {
  options.check();
  const auto start = Clock::now();
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
  if (!options.gravity_file.empty()) gravity = read_gravity_file(options.gravity_file, model);

  std::vector<Camera> cameras;
  std::map<int, camera_t> camera_index;
  for (const auto& [id, camera] : model.cameras) {
    camera_index[id] = static_cast<camera_t>(cameras.size());
    cameras.push_back(camera);
  }
  std::vector<MapperFrame> frames(model.images.size());
  for (size_t i = 0; i < model.images.size(); ++i) {
    const ColmapImage& image = model.images[i];
    MapperFrame& f = frames[i];
    f.name = image.name;
    f.camera = camera_index.at(image.camera_id);
    f.cam_from_world = image.cam_from_world;
    f.is_query = !options.query_prefix.empty() && image.name.rfind(options.query_prefix, 0) == 0;
    if (!gravity.empty()) f.gravity_in_cam = gravity.at(image.name);
  }

  const int previous_cv_threads = cv::getNumThreads();
  cv::setNumThreads(1);  // parallelism comes from our own threads
  MapperStats stats;
  try {
    parallel_for(static_cast<int64_t>(frames.size()), options.threads, [&](int64_t i, int) {
      MapperFrame& f = frames[i];
      const fs::path path = image_dir / f.name;
      const cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
      LMB_CHECK(!image.empty(), path.string() << ": cannot read image (unreadable or not an image)");
      const Camera& camera = cameras[f.camera];
      LMB_CHECK(image.cols == camera.width && image.rows == camera.height,
                path.string() << ": image is " << image.cols << "x" << image.rows << " but its camera is "
                              << camera.width << "x" << camera.height);
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
  LandmarkMap map = build_landmark_map(cameras, frames, options.detector.detector,
                                       detector_descriptor_bytes(options.detector.detector), options, &stats);
  stats.total_seconds = seconds_since(start);
  if (stats_out) *stats_out = stats;
  return map;
}

}  // namespace lmb
