#include "infer/area_bundle.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>
#include <tuple>

#include "common/error.h"
#include "common/file_container.h"
#include "common/file_io.h"
#include "common/text_lines.h"
#include "common/text_parse.h"

namespace lmb {

namespace {

void check_area_search(AreaSearch search, AreaWinner winner, const char* where) {
  LMB_CHECK(search == AreaSearch::kNearestFirst || search == AreaSearch::kAll || search == AreaSearch::kWinnersView,
            where << ": unknown area search " << static_cast<int32_t>(search));
  LMB_CHECK(winner == AreaWinner::kSupport || winner == AreaWinner::kInliers,
            where << ": unknown area winner " << static_cast<int32_t>(winner));
}

void check_area_threads(int threads, const char* where) {
  LMB_CHECK(threads >= 1 && threads <= 256, where << ": area_threads = " << threads << " must be in 1..256");
}

// Adds a scored area's correspondences to the frame's candidate points per keypoint (a landmark
// that two overlapping areas both match to a keypoint is one candidate).
void add_candidates(const Model& model, const LocalizeResult& r, std::vector<std::vector<Eigen::Vector3d>>* points) {
  for (size_t i = 0; i < r.correspondence_keypoint.size(); ++i) {
    std::vector<Eigen::Vector3d>& list = (*points)[static_cast<size_t>(r.correspondence_keypoint[i])];
    const Eigen::Vector3d& p = model.class_position(r.matches.matches[r.correspondence_match[i]].cls);
    if (std::find(list.begin(), list.end(), p) == list.end()) list.push_back(p);
  }
}

uint64_t parse_unsigned(const std::string& token, const std::string& where, const std::string& field, int base,
                        uint64_t max) {
  const char* begin = token.c_str();
  char* end = nullptr;
  errno = 0;
  const unsigned long long v = token.empty() || token[0] == '-' ? 0 : std::strtoull(begin, &end, base);
  LMB_CHECK(!token.empty() && token[0] != '-' && end == begin + token.size() && errno != ERANGE && v <= max,
            where << ": " << field << " is not a number in 0.." << max << ": '" << token << "'");
  return v;
}

}  // namespace

double BundleArea::distance(const Eigen::Vector3d& p) const {
  double sq = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double d = p[a] < cell_lo[a] ? cell_lo[a] - p[a] : (p[a] > cell_hi[a] ? p[a] - cell_hi[a] : 0.0);
    sq += d * d;
  }
  return std::sqrt(sq);
}

void write_bundle_index(const std::filesystem::path& path, double reach, const std::vector<BundleArea>& areas,
                        const PoseCalibration* calibration) {
  LMB_CHECK(std::isfinite(reach) && reach >= 0.0, path.string() << ": reach " << reach << " must be finite and >= 0");
  if (calibration != nullptr) calibration->check(path.string() + ": calibration");
  std::ostringstream os;
  os << "lmb-bundle " << (calibration != nullptr ? 2 : 1) << "\n";
  os << "# area ID file FILE bytes N crc32 HEX landmarks N cell LO_X LO_Y LO_Z HI_X HI_Y HI_Z\n";
  os << "reach " << exact_number_text(reach) << "\n";
  if (calibration != nullptr) {
    os << "# calibration W0..W" << PoseEvidence::kNumFeatures - 1
       << " BIAS THRESHOLD SAMPLES POSITIVE TARGET_PRECISION (infer/pose_confidence.h)\n";
    os << "calibration";
    for (double w : calibration->weights) os << " " << exact_number_text(w);
    os << " " << exact_number_text(calibration->bias) << " " << exact_number_text(calibration->threshold) << " "
       << calibration->num_samples << " " << calibration->num_positive << " "
       << exact_number_text(calibration->target_precision) << "\n";
  }
  os << "areas " << areas.size() << "\n";
  for (size_t i = 0; i < areas.size(); ++i) {
    const BundleArea& a = areas[i];
    LMB_CHECK(a.id == static_cast<int32_t>(i), path.string() << ": area " << i << " has id " << a.id);
    LMB_CHECK(!a.file.empty() && a.file.find_first_of(" \t\n\r") == std::string::npos,
              path.string() << ": area " << i << ": file name '" << a.file << "' is empty or has white space");
    char crc[16];
    std::snprintf(crc, sizeof(crc), "%08x", a.crc32);
    os << "area " << a.id << " file " << a.file << " bytes " << a.bytes << " crc32 " << crc << " landmarks "
       << a.landmarks << " cell";
    for (int k = 0; k < 3; ++k) os << " " << exact_number_text(a.cell_lo[k]);
    for (int k = 0; k < 3; ++k) os << " " << exact_number_text(a.cell_hi[k]);
    os << "\n";
  }
  write_file_atomically(path, os.str());
}

std::shared_ptr<AreaBundle> AreaBundle::open(const std::filesystem::path& index) {
  TextLineReader in(index);
  auto bundle = std::shared_ptr<AreaBundle>(new AreaBundle());
  bundle->index_ = index;
  int version = 1;
  auto expect = [&](const char* key, size_t count) {
    LMB_CHECK(in.next(), index.string() << ": ends before the '" << key << "' line");
    std::vector<std::string> t = in.tokens();
    LMB_CHECK(!t.empty() && t[0] == key && t.size() == count + 1,
              in.where() << ": expected '" << key << "' and " << count << " value(s), found '" << in.line() << "'");
    t.erase(t.begin());
    return t;
  };
  {
    const auto t = expect("lmb-bundle", 1);
    LMB_CHECK(t[0] == "1" || t[0] == "2",
              in.where() << ": format version " << t[0] << " is not supported (this build reads 1 and 2)");
    version = t[0] == "2" ? 2 : 1;
  }
  // (Each line's tokens are read before in.where() names it: argument order is unspecified.)
  const std::string reach = expect("reach", 1)[0];
  bundle->reach_ = parse_finite_number(reach, in.where(), "reach");
  LMB_CHECK(bundle->reach_ >= 0.0, in.where() << ": reach " << bundle->reach_ << " is negative");
  if (version == 2) {
    constexpr size_t kF = PoseEvidence::kNumFeatures;
    const auto t = expect("calibration", kF + 5);
    const std::string w = in.where();
    PoseCalibration c;
    for (size_t k = 0; k < kF; ++k) c.weights[k] = parse_finite_number(t[k], w, "calibration weight");
    c.bias = parse_finite_number(t[kF], w, "calibration bias");
    c.threshold = parse_finite_number(t[kF + 1], w, "calibration threshold");
    c.num_samples = static_cast<int64_t>(parse_unsigned(t[kF + 2], w, "calibration samples", 10, INT64_MAX));
    c.num_positive = static_cast<int64_t>(parse_unsigned(t[kF + 3], w, "calibration positives", 10, INT64_MAX));
    c.target_precision = parse_finite_number(t[kF + 4], w, "calibration target precision");
    c.check(w + ": calibration");
    bundle->calibration_ = c;
  }
  const std::string areas = expect("areas", 1)[0];
  const uint64_t num_areas = parse_unsigned(areas, in.where(), "areas", 10, 1000000);
  LMB_CHECK(num_areas >= 1, in.where() << ": a bundle needs at least one area");
  for (uint64_t i = 0; i < num_areas; ++i) {
    const auto t = expect("area", 16);
    const std::string w = in.where();
    BundleArea a;
    a.id = static_cast<int32_t>(parse_unsigned(t[0], w, "area id", 10, 1000000));
    LMB_CHECK(static_cast<uint64_t>(a.id) == i, w << ": area id " << a.id << ", expected " << i);
    const char* names[5] = {"file", "bytes", "crc32", "landmarks", "cell"};
    const int at[5] = {1, 3, 5, 7, 9};
    for (int k = 0; k < 5; ++k) {
      LMB_CHECK(t[at[k]] == names[k], w << ": expected '" << names[k] << "', found '" << t[at[k]] << "'");
    }
    a.file = t[2];
    LMB_CHECK(std::filesystem::path(a.file).is_relative(), w << ": file '" << a.file << "' must be relative");
    a.bytes = parse_unsigned(t[4], w, "bytes", 10, UINT64_MAX);
    LMB_CHECK(t[6].size() == 8, w << ": crc32 is not 8 hex digits: '" << t[6] << "'");
    a.crc32 = static_cast<uint32_t>(parse_unsigned(t[6], w, "crc32", 16, UINT32_MAX));
    a.landmarks = static_cast<int64_t>(parse_unsigned(t[8], w, "landmarks", 10, INT32_MAX));
    for (int k = 0; k < 3; ++k) a.cell_lo[k] = parse_number_or_infinity(t[10 + k], w, "cell");
    for (int k = 0; k < 3; ++k) a.cell_hi[k] = parse_number_or_infinity(t[13 + k], w, "cell");
    for (int k = 0; k < 3; ++k) {
      LMB_CHECK(a.cell_lo[k] <= a.cell_hi[k], w << ": cell lower end above its upper end on axis " << k);
      LMB_CHECK(a.cell_lo[k] < std::numeric_limits<double>::infinity() &&
                    a.cell_hi[k] > -std::numeric_limits<double>::infinity(),
                w << ": cell on axis " << k << " lies at infinity");
    }
    bundle->areas_.push_back(std::move(a));
  }
  LMB_CHECK(!in.next(), in.where() << ": unexpected line after the last area");
  bundle->models_.resize(bundle->areas_.size());
  bundle->last_use_.assign(bundle->areas_.size(), 0);
  bundle->view_samples_.resize(bundle->areas_.size());
  return bundle;
}

void PositionPrior::check() const {
  LMB_CHECK(position.allFinite(), "position prior: the position is not finite");
  LMB_CHECK(std::isfinite(radius) && radius >= 0.0, "position prior: radius " << radius << " must be finite and >= 0");
}

std::vector<int32_t> AreaBundle::select(const PositionPrior* prior) const {
  std::vector<int32_t> ids;
  if (prior != nullptr) prior->check();
  for (const BundleArea& a : areas_) {
    if (prior == nullptr || a.distance(prior->position) <= prior->radius + reach_) ids.push_back(a.id);
  }
  return ids;
}

std::shared_ptr<const Model> AreaBundle::model(int32_t id) {
  LMB_CHECK(id >= 0 && static_cast<size_t>(id) < areas_.size(),
            index_.string() << ": no area " << id << " (the bundle has " << areas_.size() << ")");
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (models_[static_cast<size_t>(id)]) {
      last_use_[static_cast<size_t>(id)] = ++use_clock_;
      return models_[static_cast<size_t>(id)];
    }
  }
  const BundleArea& a = areas_[static_cast<size_t>(id)];
  const std::filesystem::path path = index_.parent_path() / a.file;
  const std::string what = index_.parent_path().string() + ": area " + std::to_string(id) + " (" + a.file + ")";
  std::string image;
  try {
    image = read_file(path, a.bytes + 1);
  } catch (const Error& e) {
    LMB_FAIL(what << ": " << e.what());
  }
  LMB_CHECK(image.size() == a.bytes, what << ": " << image.size() << " bytes, the bundle index says " << a.bytes
                                          << " (a different or damaged file)");
  const uint32_t crc = crc32(reinterpret_cast<const uint8_t*>(image.data()), image.size());
  LMB_CHECK(crc == a.crc32, what << ": CRC-32 mismatch with the bundle index (a different or damaged file)");
  std::shared_ptr<const Model> model =
      Model::from_bytes(reinterpret_cast<const uint8_t*>(image.data()), image.size(), what);
  ModelTransform transform;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    transform = transform_;
  }
  if (transform) {
    const int32_t classes = model->num_classes();
    try {
      model = transform(id, std::move(model));
    } catch (const std::exception& e) {
      LMB_FAIL(what << ": " << e.what());
    }
    LMB_CHECK(model != nullptr && model->num_classes() == classes,
              what << ": the bundle's model transform returned " << (model ? "a model of other classes" : "no model"));
  }
  std::lock_guard<std::mutex> lock(mutex_);
  // One descriptor length for every area: a frame's descriptors are read with it.
  LMB_CHECK(descriptor_bytes_ < 0 || model->descriptor_bytes() == descriptor_bytes_,
            what << ": " << model->descriptor_bytes() << "-byte descriptors, the bundle's areas loaded before have "
                 << descriptor_bytes_);
  descriptor_bytes_ = model->descriptor_bytes();
  const size_t i = static_cast<size_t>(id);
  last_use_[i] = ++use_clock_;
  if (!view_samples_[i]) {
    // Every landmark up to kViewSample, else an even stride over the classes (deterministic).
    auto sample = std::make_shared<std::vector<Eigen::Vector3d>>();
    const size_t n = static_cast<size_t>(model->num_classes());
    const size_t count = std::min(n, kViewSample);
    sample->reserve(count);
    for (size_t k = 0; k < count; ++k) sample->push_back(model->class_position(static_cast<int32_t>(k * n / count)));
    view_samples_[i] = std::move(sample);
  }
  if (!models_[i]) {
    models_[i] = std::move(model);
    ++loads_;
    evict_locked(id);
  }
  return models_[i];
}

void AreaBundle::set_model_transform(ModelTransform transform) {
  std::lock_guard<std::mutex> lock(mutex_);
  transform_ = std::move(transform);
  for (auto& m : models_) m.reset();
}

void AreaBundle::evict_locked(int32_t keep) {
  for (;;) {
    int64_t count = 0;
    uint64_t bytes = 0;
    int32_t oldest = -1;
    for (size_t i = 0; i < models_.size(); ++i) {
      if (!models_[i]) continue;
      ++count;
      bytes += areas_[i].bytes;
      if (static_cast<int32_t>(i) != keep && (oldest < 0 || last_use_[i] < last_use_[static_cast<size_t>(oldest)])) {
        oldest = static_cast<int32_t>(i);
      }
    }
    const bool over =
        (limits_.max_areas > 0 && count > limits_.max_areas) || (limits_.max_bytes > 0 && bytes > limits_.max_bytes);
    if (!over || oldest < 0) return;
    models_[static_cast<size_t>(oldest)].reset();
  }
}

void AreaBundle::set_cache_limits(const BundleCacheLimits& limits) {
  LMB_CHECK(limits.max_areas >= 0, "bundle cache: max_areas = " << limits.max_areas << " must be >= 0 (0 = no limit)");
  std::lock_guard<std::mutex> lock(mutex_);
  limits_ = limits;
  // The most recently used area is kept, as after a load.
  int32_t newest = -1;
  for (size_t i = 0; i < models_.size(); ++i) {
    if (models_[i] && (newest < 0 || last_use_[i] > last_use_[static_cast<size_t>(newest)])) {
      newest = static_cast<int32_t>(i);
    }
  }
  evict_locked(newest);
}

BundleCacheLimits AreaBundle::cache_limits() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return limits_;
}

std::vector<int32_t> AreaBundle::loaded_ids() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<int32_t> ids;
  for (size_t i = 0; i < models_.size(); ++i) {
    if (models_[i]) ids.push_back(static_cast<int32_t>(i));
  }
  return ids;
}

uint64_t AreaBundle::loaded_bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  uint64_t bytes = 0;
  for (size_t i = 0; i < models_.size(); ++i) {
    if (models_[i]) bytes += areas_[i].bytes;
  }
  return bytes;
}

int64_t AreaBundle::loads() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return loads_;
}

int32_t AreaBundle::visible_landmarks(int32_t id, const Camera& camera, const Rigid3d& cam_from_world) {
  std::shared_ptr<const std::vector<Eigen::Vector3d>> sample;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (id >= 0 && static_cast<size_t>(id) < view_samples_.size()) sample = view_samples_[static_cast<size_t>(id)];
  }
  if (!sample) {
    model(id);  // loads it (or throws naming it)
    std::lock_guard<std::mutex> lock(mutex_);
    sample = view_samples_[static_cast<size_t>(id)];
  }
  int32_t visible = 0;
  for (const Eigen::Vector3d& p : *sample) {
    const Eigen::Vector3d in_cam = cam_from_world * p;
    Eigen::Vector2d px;
    if (in_cam.z() <= 0.0 || (reach_ > 0.0 && in_cam.norm() > reach_) || !camera.project(in_cam, &px)) continue;
    visible += px.x() >= 0.0 && px.y() >= 0.0 && px.x() < camera.width && px.y() < camera.height;
  }
  return visible;
}

int32_t AreaBundle::descriptor_bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return descriptor_bytes_;
}

int32_t AreaBundle::descriptor_bytes(const std::vector<int32_t>& ids) {
  for (size_t i = 0; descriptor_bytes() < 0 && i < ids.size(); ++i) {
    try {
      model(ids[i]);
    } catch (const Error&) {
      // A missing or damaged area: the next one may tell.
    }
  }
  return descriptor_bytes();
}

bool AreaBundle::loaded(int32_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return id >= 0 && static_cast<size_t>(id) < models_.size() && models_[static_cast<size_t>(id)] != nullptr;
}

void AreaBundle::release_except(const std::vector<int32_t>& keep) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (size_t i = 0; i < models_.size(); ++i) {
    if (std::find(keep.begin(), keep.end(), static_cast<int32_t>(i)) == keep.end()) models_[i].reset();
  }
}

namespace {

// Sorts area ids by their cell's distance from `position` (ties keep their order).
void order_by_distance(const AreaBundle& bundle, const Eigen::Vector3d& position, std::vector<int32_t>* ids) {
  const std::vector<BundleArea>& areas = bundle.areas();
  std::stable_sort(ids->begin(), ids->end(), [&](int32_t a, int32_t b) {
    return areas[static_cast<size_t>(a)].distance(position) < areas[static_cast<size_t>(b)].distance(position);
  });
}

// One area's localization of the frame, or why its model could not be loaded.
struct AreaRun {
  std::shared_ptr<const Model> model;  // null when it could not be loaded
  std::string error;
  bool loaded_now = false;  // read from its file by this call
  LocalizeResult result;
};

// The areas `selected` localize the frame in this order, `threads` at a time (waves of that many,
// each area on its own thread); nearest_first: the search stops as AreaSearch::kNearestFirst says,
// and the areas after the stopping one in its wave are dropped, so that the result is the
// one-thread result whatever the thread count. `gate` (track()): once `gate_areas` areas are scored,
// the search also stops where the verdict's winner lies within the gate, and an area's own
// calibration no longer stops it; result.tracked: the winner lies within the gate, however the
// search ended. `view_prior` (AreaSearch::kWinnersView): after each scored area whose verdict has a
// new winner, the areas not yet scored are re-ranked by how many of their landmarks the winning
// pose sees, then by their distance from view_prior's position, then by id; a wave runs the next
// `threads` areas of the current order not yet run, and an area run ahead is used when the order
// reaches it (or never), so the result is again the one-thread result. `start`: when the call
// began (total_ms).
BundleLocalizeResult localize_selected(AreaBundle& bundle, const std::vector<int32_t>& selected, bool nearest_first,
                                       const PositionPrior* gate, int gate_areas, const PositionPrior* view_prior,
                                       const Camera& camera, const std::vector<Keypoint>& keypoints,
                                       const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam,
                                       const LocalizerOptions& options, AreaWinner winner, int threads,
                                       std::chrono::steady_clock::time_point start) {
  using Clock = std::chrono::steady_clock;
  BundleLocalizeResult out;
  out.selected = static_cast<int32_t>(selected.size());
  std::mutex prepared_mutex;
  std::shared_ptr<const PreparedFrame> prepared;  // guarded by prepared_mutex
  const auto run_area = [&](int32_t id, AreaRun* run) {
    // (`loaded_now` is exact for one caller at a time: another may load the same area meanwhile.)
    run->loaded_now = !bundle.loaded(id);
    try {
      run->model = bundle.model(id);
    } catch (const Error& e) {
      run->error = e.what();
      run->loaded_now = false;
      return;
    }
    // The frame's words, placed keypoints and context index: once for every area of one vocabulary
    // (all of a bundle's, as `lboost train --area` makes them), by the first area to need them.
    std::shared_ptr<const PreparedFrame> frame;
    {
      const std::lock_guard<std::mutex> lock(prepared_mutex);
      if (prepared == nullptr) {
        prepared = std::make_shared<const PreparedFrame>(run->model, camera, keypoints, descriptors, gravity_in_cam);
      }
      if (prepared->serves(*run->model)) frame = prepared;
    }
    const Localizer localizer(run->model, options);
    run->result = frame != nullptr ? localizer.localize(camera, keypoints, descriptors, *frame, options)
                                   : localizer.localize(camera, keypoints, descriptors, gravity_in_cam, options);
  };
  // Every scored area's matches (per keypoint, distinct 3D points) and its result while it may win.
  std::vector<std::vector<Eigen::Vector3d>> candidates(keypoints.size());
  std::vector<LocalizeResult> posed;  // per scored area: its result when it has a pose
  std::vector<size_t> posed_index;    // per scored area: index into posed, or SIZE_MAX
  std::vector<Eigen::Vector2d> pixels(keypoints.size());
  for (size_t k = 0; k < keypoints.size(); ++k) pixels[k] = Eigen::Vector2d(keypoints[k].x, keypoints[k].y);
  const std::vector<Eigen::Vector3d> bearings = keypoint_bearings(camera, pixels);  // once: judged per area
  const bool calibrated = bundle.calibrated();
  const double threshold = !calibrated                     ? -1.0
                           : options.min_confidence >= 0.0 ? options.min_confidence
                                                           : bundle.calibration().threshold;
  // The verdict over the areas scored so far: each pose's support over their matches, the winner
  // (`forced`: that scored index, else by the winner rule), its rival and the bundle's evidence and
  // confidence (-1 without a calibration).
  struct Verdict {
    size_t best = SIZE_MAX;
    std::vector<int32_t> support;  // per scored area
    int32_t rival = 0;
    PoseEvidence evidence;
    double confidence = -1.0;
  };
  const auto judge = [&](size_t forced) {
    Verdict v;
    std::vector<Rigid3d> poses;
    for (const LocalizeResult& r : posed) poses.push_back(r.pose.cam_from_world);
    const std::vector<int> support =
        count_explained_keypoints(camera, bearings, candidates, poses, options.pose.max_reprojection_error_px);
    v.support.assign(out.scored.size(), 0);
    for (size_t i = 0; i < out.scored.size(); ++i) {
      if (posed_index[i] == SIZE_MAX) continue;
      v.support[i] = support[posed_index[i]];
      const auto key = [&](size_t j) {
        const int32_t rule = winner == AreaWinner::kSupport ? v.support[j] : 0;
        return std::make_tuple(rule, out.inliers[j], -out.scored[j]);
      };
      if (v.best == SIZE_MAX || key(i) > key(v.best)) v.best = i;
    }
    if (forced != SIZE_MAX) v.best = forced;
    if (v.best == SIZE_MAX) return v;
    const Rigid3d winner_pose = poses[posed_index[v.best]];
    const std::vector<int> rival = count_explained_keypoints(camera, bearings, candidates, poses,
                                                             options.pose.max_reprojection_error_px, &winner_pose);
    for (size_t j = 0; j < rival.size(); ++j) {
      if (j != posed_index[v.best]) v.rival = std::max(v.rival, rival[j]);
    }
    PoseEvidence& e = v.evidence;
    e = posed[posed_index[v.best]].evidence;  // its area's inlier rank and spread
    e.num_keypoints = static_cast<int>(keypoints.size());
    e.num_correspondences = static_cast<int>(
        std::count_if(candidates.begin(), candidates.end(), [](const auto& list) { return !list.empty(); }));
    e.num_inliers = v.support[v.best];
    e.runner_up_inliers = v.rival;
    if (calibrated) v.confidence = bundle.calibration().probability(e);
    return v;
  };
  // Whether the verdict's winner passes the gate: its pose lies within it and explains more
  // keypoints than its rival (a look-alike pose as strong as another is no track to follow).
  const auto passes_gate = [&](const Verdict& v) {
    return gate != nullptr && v.best != SIZE_MAX && posed_index[v.best] != SIZE_MAX && v.support[v.best] > v.rival &&
           (posed[posed_index[v.best]].pose.cam_from_world.center() - gate->position).norm() <= gate->radius;
  };
  Verdict verdict;
  bool verdict_current = false;  // `verdict` is over every area scored
  size_t forced = SIZE_MAX;      // an area's own calibrated pose stopped the search: it wins
  bool stopped = false;
  std::vector<int32_t> order = selected;  // the search's order (re-ranked with view_prior)
  std::map<int32_t, AreaRun> ahead;       // areas a wave ran that the order has not reached yet
  size_t ranked_by = SIZE_MAX;            // the scored index whose pose's view ranked `order`
  for (size_t next = 0; next < order.size() && !stopped; ++next) {
    auto found = ahead.find(order[next]);
    if (found == ahead.end()) {
      // A wave: this area and the next ones of the current order not yet run, `threads` in all.
      std::vector<int32_t> wave{order[next]};
      for (size_t j = next + 1; j < order.size() && wave.size() < static_cast<size_t>(threads); ++j) {
        if (ahead.count(order[j]) == 0) wave.push_back(order[j]);
      }
      std::vector<AreaRun> runs(wave.size());
      if (wave.size() == 1) {
        run_area(wave[0], &runs[0]);
      } else {
        std::vector<std::exception_ptr> failures(wave.size());
        std::vector<std::thread> workers;
        for (size_t i = 0; i < wave.size(); ++i) {
          workers.emplace_back([&, i] {
            try {
              run_area(wave[i], &runs[i]);
            } catch (...) {
              failures[i] = std::current_exception();
            }
          });
        }
        for (std::thread& w : workers) w.join();
        for (const std::exception_ptr& f : failures) {
          if (f) std::rethrow_exception(f);
        }
      }
      for (size_t i = 0; i < wave.size(); ++i) ahead.emplace(wave[i], std::move(runs[i]));
      found = ahead.find(order[next]);
    }
    AreaRun run = std::move(found->second);
    ahead.erase(found);
    out.loaded += run.loaded_now ? 1 : 0;
    if (!run.model) {
      out.errors.push_back(std::move(run.error));
      continue;
    }
    LocalizeResult& r = run.result;
    out.scored.push_back(order[next]);
    out.inliers.push_back(r.pose.success ? r.pose.num_inliers : 0);
    add_candidates(*run.model, r, &candidates);
    const bool area_stops = !calibrated && nearest_first && r.calibrated && r.localized;
    posed_index.push_back(r.pose.success ? posed.size() : SIZE_MAX);
    if (r.pose.success) posed.push_back(std::move(r));
    verdict_current = false;
    // With a gate, the gate and the bundle's calibration decide, not an area's own calibration.
    // (Fewer areas than gate_areas selected: the gate opens once all are scored.)
    const bool gate_open =
        gate != nullptr && out.scored.size() >= std::min(static_cast<size_t>(gate_areas), selected.size());
    if (area_stops && gate == nullptr) {
      stopped = true;
      forced = out.scored.size() - 1;
    } else if ((calibrated && nearest_first) || gate_open || view_prior != nullptr) {
      // A calibrated bundle stops at the first point where its verdict is localized; the motion
      // gate where the verdict's winner lies within it.
      verdict = judge(SIZE_MAX);
      verdict_current = true;
      stopped = (gate_open && passes_gate(verdict)) ||
                (calibrated && nearest_first && verdict.best != SIZE_MAX && verdict.confidence >= threshold);
    }
    if (!stopped && view_prior != nullptr && verdict_current && verdict.best != SIZE_MAX && verdict.best != ranked_by &&
        next + 2 < order.size()) {
      // The areas that see most of the winning pose's view next (an area that cannot load counts 0).
      ranked_by = verdict.best;
      const Rigid3d& pose = posed[posed_index[verdict.best]].pose.cam_from_world;
      std::vector<std::tuple<int32_t, double, int32_t>> rank;
      for (size_t j = next + 1; j < order.size(); ++j) {
        int32_t visible = 0;
        try {
          visible = bundle.visible_landmarks(order[j], camera, pose);
        } catch (const Error&) {
          visible = 0;
        }
        rank.emplace_back(-visible, bundle.areas()[static_cast<size_t>(order[j])].distance(view_prior->position),
                          order[j]);
      }
      std::sort(rank.begin(), rank.end());
      for (size_t j = 0; j < rank.size(); ++j) order[next + 1 + j] = std::get<2>(rank[j]);
    }
  }
  if (!verdict_current) verdict = judge(forced);
  out.tracked = passes_gate(verdict);  // however the search ended
  out.support = std::move(verdict.support);
  if (verdict.best != SIZE_MAX) {
    out.area = out.scored[verdict.best];
    out.rival_support = verdict.rival;
    out.evidence = verdict.evidence;
    out.result = std::move(posed[posed_index[verdict.best]]);
    out.localized = out.result.localized;
    if (calibrated) {
      out.calibrated = true;
      out.confidence = verdict.confidence;
      out.confidence_threshold = threshold;
      out.localized = out.confidence >= out.confidence_threshold;
    }
  }
  out.total_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  return out;
}

}  // namespace

BundleLocalizeResult localize_in_bundle(AreaBundle& bundle, const Camera& camera,
                                        const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                                        const Eigen::Vector3d& gravity_in_cam, const PositionPrior* prior,
                                        const LocalizerOptions& options, AreaSearch search, AreaWinner winner,
                                        int area_threads) {
  const auto start = std::chrono::steady_clock::now();
  options.check();
  check_area_search(search, winner, "localize_in_bundle");
  check_area_threads(area_threads, "localize_in_bundle");
  std::vector<int32_t> selected = bundle.select(prior);
  const bool nearest_first = prior != nullptr && search != AreaSearch::kAll;
  if (nearest_first) order_by_distance(bundle, prior->position, &selected);
  const PositionPrior* view_prior = nearest_first && search == AreaSearch::kWinnersView ? prior : nullptr;
  BundleLocalizeResult out =
      localize_selected(bundle, selected, nearest_first, nullptr, 1, view_prior, camera, keypoints, descriptors,
                        gravity_in_cam, options, winner, area_threads, start);
  out.prior_used = prior != nullptr;
  return out;
}

BundleLocalizeResult localize_in_areas(AreaBundle& bundle, const std::vector<int32_t>& ids, const Camera& camera,
                                       const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                                       const Eigen::Vector3d& gravity_in_cam, const LocalizerOptions& options,
                                       AreaWinner winner, int area_threads) {
  const auto start = std::chrono::steady_clock::now();
  options.check();
  check_area_search(AreaSearch::kAll, winner, "localize_in_areas");
  check_area_threads(area_threads, "localize_in_areas");
  for (size_t i = 0; i < ids.size(); ++i) {
    LMB_CHECK(ids[i] >= 0 && static_cast<size_t>(ids[i]) < bundle.areas().size(),
              "localize_in_areas: no area " << ids[i] << " (the bundle has " << bundle.areas().size() << ")");
    LMB_CHECK(std::find(ids.begin(), ids.begin() + static_cast<std::ptrdiff_t>(i), ids[i]) ==
                  ids.begin() + static_cast<std::ptrdiff_t>(i),
              "localize_in_areas: area " << ids[i] << " is listed twice");
  }
  return localize_selected(bundle, ids, false, nullptr, 1, nullptr, camera, keypoints, descriptors, gravity_in_cam,
                           options, winner, area_threads, start);
}

void BundleLocalizerOptions::check() const {
  localizer.check();
  LMB_CHECK(std::isfinite(tracking_radius) && tracking_radius >= 0.0,
            "bundle localizer options: tracking_radius = " << tracking_radius << " must be finite and >= 0");
  check_area_search(search, winner, "bundle localizer options");
  check_area_threads(area_threads, "bundle localizer options");
  LMB_CHECK(tracking_areas >= 1 && tracking_areas <= 256,
            "bundle localizer options: tracking_areas = " << tracking_areas << " must be in 1..256");
}

BundleLocalizer::BundleLocalizer(std::shared_ptr<AreaBundle> bundle, const BundleLocalizerOptions& options)
    : bundle_(std::move(bundle)), options_(options) {
  LMB_CHECK(bundle_ != nullptr, "bundle localizer: null bundle");
  options_.check();
}

BundleLocalizeResult BundleLocalizer::localize(const Camera& camera, const std::vector<Keypoint>& keypoints,
                                               const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam,
                                               const PositionPrior* prior) const {
  return localize_in_bundle(*bundle_, camera, keypoints, descriptors, gravity_in_cam, prior, options_.localizer,
                            options_.search, options_.winner, options_.area_threads);
}

BundleLocalizeResult BundleLocalizer::track(const Camera& camera, const std::vector<Keypoint>& keypoints,
                                            const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam,
                                            const PositionPrior* relocalization_prior) {
  const auto start = std::chrono::steady_clock::now();
  // A bad relocalization prior is an error on every frame, not only on the frames that relocalize.
  if (relocalization_prior != nullptr) relocalization_prior->check();
  // A pose to track from: one within the motion gate of the last tracked pose, or with a calibrated
  // bundle one it reports localized (a wrong pose must not become the next prior), else any winning pose.
  const auto trusted = [](const BundleLocalizeResult& x) { return x.calibrated ? x.localized : x.area >= 0; };
  BundleLocalizeResult r;
  bool done = false;
  PositionPrior prior;  // with a last position: the tracked areas' prior and the motion gate
  if (last_position_) {
    prior.position = *last_position_;
    // The camera moves at most tracking_radius a frame: after frames without a tracked pose, further.
    prior.radius = options_.tracking_radius * static_cast<double>(1 + frames_since_pose_);
    const bool nearest_first = options_.search != AreaSearch::kAll;
    std::vector<int32_t> selected = bundle_->select(&prior);
    const int64_t loads_before = bundle_->loads();
    if (nearest_first) {
      // The areas that see most of the last pose's view first (by a sample of their landmarks), then
      // the nearest, then the smaller id. An area that cannot load counts 0 (scoring reports it).
      std::vector<std::tuple<int32_t, double, int32_t>> order;
      for (int32_t id : selected) {
        int32_t visible = 0;
        if (last_pose_) {
          try {
            visible = bundle_->visible_landmarks(id, camera, *last_pose_);
          } catch (const Error&) {
            visible = 0;
          }
        }
        order.emplace_back(-visible, bundle_->areas()[static_cast<size_t>(id)].distance(prior.position), id);
      }
      std::sort(order.begin(), order.end());
      for (size_t i = 0; i < order.size(); ++i) selected[i] = std::get<2>(order[i]);
    }
    const int32_t ranked_loads = static_cast<int32_t>(bundle_->loads() - loads_before);
    r = localize_selected(*bundle_, selected, nearest_first, nearest_first ? &prior : nullptr, options_.tracking_areas,
                          nullptr, camera, keypoints, descriptors, gravity_in_cam, options_.localizer, options_.winner,
                          options_.area_threads, start);
    r.loaded += ranked_loads;
    r.prior_used = true;
    done = r.tracked || trusted(r) || !options_.relocalize_without_prior;
  }
  if (!done) {
    const int32_t loaded = r.loaded;
    std::vector<std::string> errors = std::move(r.errors);
    // Relocalization: the areas `relocalization_prior` selects, nearest first, or every area. With a
    // last pose, a winner inside its gate is tracked too (judged once all are scored, so the gate
    // does not stop the search early), e.g. the right pose after a lost frame.
    std::vector<int32_t> ids = bundle_->select(relocalization_prior);
    const bool nearest = relocalization_prior != nullptr && options_.search != AreaSearch::kAll;
    if (nearest) order_by_distance(*bundle_, relocalization_prior->position, &ids);
    r = localize_selected(
        *bundle_, ids, nearest, last_position_ ? &prior : nullptr, std::max(1, static_cast<int>(ids.size())),
        nearest && options_.search == AreaSearch::kWinnersView ? relocalization_prior : nullptr, camera, keypoints,
        descriptors, gravity_in_cam, options_.localizer, options_.winner, options_.area_threads, start);
    // The failed tracking attempt's time and loads count too.
    r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    r.loaded += loaded;
    for (std::string& e : r.errors) {
      if (std::find(errors.begin(), errors.end(), e) == errors.end()) errors.push_back(std::move(e));
    }
    r.errors = std::move(errors);
  }
  if (r.tracked || trusted(r)) {
    set_last_pose(r.result.pose.cam_from_world);
  } else if (last_position_) {
    ++frames_since_pose_;
  }
  return r;
}

void BundleLocalizer::set_last_pose(const std::optional<Rigid3d>& cam_from_world) {
  last_pose_ = cam_from_world;
  last_position_.reset();
  frames_since_pose_ = 0;
  if (cam_from_world) last_position_ = cam_from_world->center();
}

}  // namespace lmb
