#include "train/eval/bundle_eval.h"

#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <optional>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/feature_space.h"
#include "common/io/map_h5.h"
#include "common/landmark_map.h"
#include "common/stats.h"
#include "infer/model.h"
#include "train/areas/area_split.h"
#include "train/eval/evaluation.h"

namespace lmb {

namespace {

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

// Resident memory of this process, bytes (Linux /proc/self/statm; 0 when unreadable).
int64_t resident_bytes() {
  std::ifstream in("/proc/self/statm");
  int64_t size = 0, resident = 0;
  if (!(in >> size >> resident)) return 0;
  return resident * static_cast<int64_t>(sysconf(_SC_PAGESIZE));
}

std::string hex_text(uint64_t v) {
  char buf[24];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

std::string number_text(double metres) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", metres);
  return buf;
}

// One frame's outcome in one mode at one seed.
struct Outcome {
  bool success = false;
  Rigid3d pose;
  int inliers = 0;
  int32_t area = -1;
  int32_t selected = 0, loaded = 0;
  // The areas scored, in order, their poses' inliers and support (BundleLocalizeResult).
  std::vector<int32_t> scored, scored_inliers, scored_support;
  int32_t rival_support = 0;                 // the winner's rival (BundleLocalizeResult)
  bool localized = false;                    // the answer to act on (BundleLocalizeResult::localized)
  double confidence = -1.0;                  // the calibrated confidence (-1: uncalibrated)
  bool tracked = false, prior_used = false;  // tracking modes (BundleLocalizeResult)
  // Tracking with a walk calibration: the frame rule's verdict alone, and the walk's (WalkVerdict).
  bool walk_judged = false, frame_localized = false, by_walk = false, disagrees = false;
  std::vector<std::string> errors;
  double wall_ms = 0.0, cpu_ms = 0.0;
};

}  // namespace

void BundleEvalOptions::check() const {
  LMB_CHECK(!bundle.empty(), "--bundle is empty");
  for (double m : prior_noise) {
    LMB_CHECK(std::isfinite(m) && m >= 0.0, "--prior-noise " << m << ": must be finite and >= 0");
  }
  for (double m : track) {
    LMB_CHECK(std::isfinite(m) && m > 0.0, "--track " << m << ": must be finite and > 0");
  }
  LMB_CHECK(track_prior_noise < 0.0 || (std::isfinite(track_prior_noise) && !track.empty()),
            "--track-prior-noise " << track_prior_noise << ": must be finite and needs --track");
  LMB_CHECK(tracking_areas >= 1 && tracking_areas <= 256,
            "--tracking-areas " << tracking_areas << ": must be in 1..256");
  LMB_CHECK(!prior_noise.empty() || no_prior || !track.empty(),
            "--bundle needs --prior-noise METRES, --track METRES and/or --no-prior");
  LMB_CHECK(seeds >= 1 && seeds <= 100, "seeds " << seeds << ": must be in 1..100");
  LMB_CHECK(cache.max_areas >= 0, "--cache-areas " << cache.max_areas << ": must be >= 0");
  LMB_CHECK(area_threads >= 1 && area_threads <= 256, "--area-threads " << area_threads << ": must be in 1..256");
  thresholds.check();
  localizer.check();
}

namespace {

// Memory per area: the areas loaded one after the other, the growth of the process's resident
// memory at each load (freeing an area first would let the next one reuse its pages).
nlohmann::json measure_areas(AreaBundle& bundle, bool memory_per_area) {
  nlohmann::json areas = nlohmann::json::array();
  for (const BundleArea& a : bundle.areas()) {
    nlohmann::json ja = {{"id", a.id}, {"file", a.file}, {"file_bytes", a.bytes}, {"landmarks", a.landmarks}};
    if (memory_per_area) {
      const int64_t before = resident_bytes();
      const auto t0 = std::chrono::steady_clock::now();
      try {
        bundle.model(a.id);
        ja["load_ms"] = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        ja["resident_bytes"] = resident_bytes() - before;
      } catch (const Error& e) {
        ja["error"] = e.what();
      }
    }
    areas.push_back(std::move(ja));
  }
  bundle.release_except({});
  return areas;
}

struct Mode {
  std::string name;
  bool single = false;
  bool has_prior = false;
  double noise = 0.0;
  double tracking_radius = 0.0;  // > 0: a tracking mode
};

std::vector<Mode> make_modes(const BundleEvalOptions& options, bool with_single) {
  std::vector<Mode> modes;
  for (double m : options.prior_noise) {
    std::string name = "prior ";
    name += number_text(m);
    name += " m";
    modes.push_back({name, false, true, m});
  }
  if (options.no_prior) modes.push_back({"no prior", false, false, 0.0});
  for (double m : options.track) {
    std::string name = "tracking " + number_text(m) + " m";
    if (options.track_prior_noise >= 0.0)
      name += ", relocalizing with a " + number_text(options.track_prior_noise) + " m prior";
    modes.push_back({name, false, false, 0.0, m});
  }
  if (with_single) modes.push_back({"single model", true, false, 0.0});
  return modes;
}

// What the bundle's frame runs of every mode add up to: which areas failed to load, and whether
// any run scored an area at all.
struct AreaTally {
  std::map<std::string, int64_t> errors;  // each error line and how many frame runs gave it
  int64_t bundle_runs = 0;                // frame runs through the bundle
  int64_t scored_runs = 0;                // of them with at least one area scored
  void add(const Outcome& o) {
    ++bundle_runs;
    scored_runs += o.scored.empty() ? 0 : 1;
    for (const std::string& e : o.errors) ++errors[e];
  }
};

// Everything one mode's frames share.
struct ModeContext {
  const BundleEvalOptions& options;
  const LandmarkMap& map;
  const std::shared_ptr<AreaBundle>& bundle;
  const std::shared_ptr<const Model>& single;
  AreaTally* tally;
};

// One query frame localized in one mode, timed on this thread.
Outcome localize_frame(const ModeContext& c, const Mode& mode, frame_t f, const LocalizerOptions& lo,
                       BundleLocalizer* bundle_localizer) {
  const MapFrame& frame = c.map.frames[f];
  const std::vector<Keypoint> keypoints(c.map.keypoints.begin() + frame.first_keypoint,
                                        c.map.keypoints.begin() + frame.first_keypoint + frame.num_keypoints);
  const uint8_t* descriptors = c.map.descriptor(frame.first_keypoint);
  const Camera& camera = c.map.cameras[frame.camera];
  Outcome o;
  const double c0 = thread_cpu_ms();
  const auto t0 = std::chrono::steady_clock::now();
  if (mode.single) {
    const Localizer localizer(c.single, lo);
    const LocalizeResult r = localizer.localize(camera, keypoints, descriptors, frame.gravity_in_cam);
    o.success = r.pose.success;
    o.pose = r.pose.cam_from_world;
    o.inliers = r.pose.num_inliers;
    o.localized = r.localized;
    o.confidence = r.confidence;
  } else {
    // The frame's position prior: the mode's, or a tracking mode's relocalization prior.
    const bool tracking = mode.tracking_radius > 0.0;
    const double noise = tracking ? c.options.track_prior_noise : mode.has_prior ? mode.noise : -1.0;
    PositionPrior prior;
    if (noise >= 0.0) {
      prior.position = frame.cam_from_world.center() + noise * prior_direction(c.options.prior_seed, f);
      prior.radius = noise;
    }
    const PositionPrior* p = noise >= 0.0 ? &prior : nullptr;
    BundleLocalizeResult r = tracking
                                 ? bundle_localizer->track(camera, keypoints, descriptors, frame.gravity_in_cam, p)
                                 : bundle_localizer->localize(camera, keypoints, descriptors, frame.gravity_in_cam, p);
    o.tracked = r.tracked;
    o.prior_used = r.prior_used;
    o.success = r.area >= 0;
    o.pose = r.result.pose.cam_from_world;
    o.inliers = r.result.pose.num_inliers;
    o.area = r.area;
    o.selected = r.selected;
    o.scored = std::move(r.scored);
    o.scored_inliers = std::move(r.inliers);
    o.rival_support = r.rival_support;
    o.localized = r.localized;
    o.frame_localized = r.frame_localized;
    o.walk_judged = r.walk_judged;
    o.by_walk = r.walk.by_walk;
    o.disagrees = r.walk.agreement_applies && !r.walk.agrees;
    o.confidence = r.confidence;
    o.scored_support = std::move(r.support);
    o.loaded = r.loaded;
    o.errors = std::move(r.errors);
  }
  o.wall_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  o.cpu_ms = thread_cpu_ms() - c0;
  return o;
}

nlohmann::json frame_json(const MapFrame& frame, const Mode& mode, const Outcome& o, bool correct) {
  nlohmann::json jf = {{"name", frame.name},       {"success", o.success},     {"correct", correct},
                       {"num_inliers", o.inliers}, {"localized", o.localized}, {"confidence", o.confidence},
                       {"cpu_ms", o.cpu_ms},       {"wall_ms", o.wall_ms}};
  if (!mode.single) {
    jf["area"] = o.area;
    jf["areas_selected"] = o.selected;
    jf["areas_scored"] = o.scored.size();
    jf["scored"] = o.scored;
    jf["scored_inliers"] = o.scored_inliers;
    jf["scored_support"] = o.scored_support;
    const auto winner = std::find(o.scored.begin(), o.scored.end(), o.area);
    jf["support"] = winner == o.scored.end() ? 0 : o.scored_support[static_cast<size_t>(winner - o.scored.begin())];
    jf["rival_support"] = o.rival_support;
    jf["areas_loaded"] = o.loaded;
    if (mode.tracking_radius > 0.0) {
      jf["tracked"] = o.tracked;
      jf["relocalized"] = !o.prior_used;
      if (o.walk_judged) {
        jf["walk"] = {{"frame_rule_localized", o.frame_localized}, {"by_walk", o.by_walk}, {"disagrees", o.disagrees}};
      }
    }
    if (!o.errors.empty()) jf["errors"] = o.errors;
  }
  if (o.success) {
    jf["position_error_m"] = position_error(o.pose, frame.cam_from_world);
    jf["rotation_error_deg"] = rotation_error_deg(o.pose, frame.cam_from_world);
  }
  return jf;
}

// The bundle's localizer of one seed (none in the single model's mode); a tracking mode follows one
// camera a seed, from no pose.
std::optional<BundleLocalizer> seed_localizer(const ModeContext& c, const Mode& mode, const LocalizerOptions& lo) {
  if (mode.single) return std::nullopt;
  BundleLocalizerOptions bo;
  bo.localizer = lo;
  bo.search = c.options.search;
  bo.winner = c.options.winner;
  bo.area_threads = c.options.area_threads;
  bo.tracking_radius = mode.tracking_radius;
  bo.tracking_areas = c.options.tracking_areas;
  return std::optional<BundleLocalizer>(std::in_place, c.bundle, bo);
}

// A tracking mode's own figures over its frames and seeds.
struct TrackingTally {
  int64_t relocalized = 0;
  std::vector<int> tracked_per_seed, tracked_correct_per_seed;
  std::vector<double> tracked_cpu;  // thread CPU ms of the tracked frames, every seed
  // With a walk calibration: the frame rule alone's reported frames and right ones per seed, and
  // over every seed the poses the walk rule added and the ones refused for disagreeing.
  std::vector<int> frame_rule_per_seed, frame_rule_correct_per_seed;
  int64_t by_walk = 0, disagreeing = 0;
  bool walk_judged = false;
  // Per seed: the first frame reported localized (-1: none) and the thread CPU ms of the frames up
  // to and including it (-1: none): the time to the first trusted pose.
  std::vector<int64_t> first_localized;
  std::vector<double> cpu_to_first;
  int64_t seed_frames = 0;
  double seed_cpu = 0.0;

  void start_seed() {
    for (auto* v : {&tracked_per_seed, &tracked_correct_per_seed, &frame_rule_per_seed, &frame_rule_correct_per_seed}) {
      v->push_back(0);
    }
    first_localized.push_back(-1);
    cpu_to_first.push_back(-1.0);
    seed_frames = 0;
    seed_cpu = 0.0;
  }
  void add(const Outcome& o, bool ok) {
    seed_cpu += o.cpu_ms;
    if (o.localized && first_localized.back() < 0) {
      first_localized.back() = seed_frames;
      cpu_to_first.back() = seed_cpu;
    }
    ++seed_frames;
    if (o.tracked) tracked_cpu.push_back(o.cpu_ms);
    relocalized += !o.prior_used;
    tracked_per_seed.back() += o.tracked;
    tracked_correct_per_seed.back() += o.tracked && ok;
    frame_rule_per_seed.back() += o.frame_localized;
    frame_rule_correct_per_seed.back() += o.frame_localized && ok;
    walk_judged = walk_judged || o.walk_judged;
    by_walk += o.by_walk;
    disagreeing += o.disagrees;
  }
  static int sum(const std::vector<int>& v) { return std::accumulate(v.begin(), v.end(), 0); }
  void report(double runs, nlohmann::json* jm) const {
    (*jm)["tracked_per_frame"] = static_cast<double>(tracked_cpu.size()) / runs;
    (*jm)["cpu_ms_per_tracked_frame"] = {{"mean", mean(tracked_cpu)}, {"median", median(tracked_cpu)}};
    (*jm)["relocalized_per_frame"] = static_cast<double>(relocalized) / runs;
    // The frames whose pose passed the motion gate, and of them correct, per seed.
    (*jm)["tracked_frames_per_seed"] = tracked_per_seed;
    (*jm)["tracked_correct_per_seed"] = tracked_correct_per_seed;
    (*jm)["first_localized_frame_per_seed"] = first_localized;
    (*jm)["cpu_ms_to_first_localized_per_seed"] = cpu_to_first;
    if (walk_judged) {
      // `localized` is the walk's verdict; what the frame rule alone reports, beside it.
      (*jm)["walk"] = {{"frame_rule_localized_per_seed", frame_rule_per_seed},
                       {"frame_rule_localized_correct_per_seed", frame_rule_correct_per_seed},
                       {"by_walk", by_walk},
                       {"disagreeing", disagreeing}};
    }
  }
  std::string text() const {
    std::string t = "  tracked " + std::to_string(tracked_cpu.size()) + " (" +
                    std::to_string(sum(tracked_correct_per_seed)) + " right), relocalized " +
                    std::to_string(relocalized) + " (all seeds)";
    if (walk_judged) {
      t += "; frame rule alone " + std::to_string(sum(frame_rule_per_seed)) + " (" +
           std::to_string(sum(frame_rule_correct_per_seed)) + " right), by walk " + std::to_string(by_walk) +
           ", disagreeing " + std::to_string(disagreeing);
    }
    return t;
  }
};

// One mode over every frame and seed: its report entry, and its line of the table.
nlohmann::json evaluate_mode(const ModeContext& c, const Mode& mode, const std::vector<frame_t>& frames,
                             std::string* table) {
  std::vector<int> correct_per_seed, trusted_per_seed, trusted_correct_per_seed;
  std::vector<double> cpu, wall, pos_err;
  double selected = 0, scored = 0, loaded = 0, localized = 0;
  int64_t runs = 0;
  const int64_t loads_before = c.bundle->loads();
  nlohmann::json jframes = nlohmann::json::array();
  // Progress: a line every 30 s of wall time and after each seed, with the mode's ETA.
  const auto started = std::chrono::steady_clock::now();
  auto last_line = started;
  const int64_t total_runs = static_cast<int64_t>(frames.size()) * c.options.seeds;
  const auto progress = [&](int seed, bool seed_done) {
    const auto now = std::chrono::steady_clock::now();
    if (!seed_done && now - last_line < std::chrono::seconds(30)) return;
    last_line = now;
    const double elapsed = std::chrono::duration<double>(now - started).count();
    const double eta = runs > 0 ? elapsed * static_cast<double>(total_runs - runs) / static_cast<double>(runs) : 0.0;
    spdlog::info("eval --bundle: {}: seed {}/{}, {} of {} frame runs, {:.0f} s, ETA {:.0f} s", mode.name, seed + 1,
                 c.options.seeds, runs, total_runs, elapsed, eta);
  };
  TrackingTally tracking;
  for (int s = 0; s < c.options.seeds; ++s) {
    LocalizerOptions lo = c.options.localizer;
    lo.pose.seed = c.options.localizer.pose.seed + static_cast<uint64_t>(s);
    int correct = 0, trusted = 0, trusted_correct = 0;
    tracking.start_seed();
    std::optional<BundleLocalizer> localizer = seed_localizer(c, mode, lo);
    for (frame_t f : frames) {
      const MapFrame& frame = c.map.frames[f];
      const Outcome o = localize_frame(c, mode, f, lo, localizer ? &*localizer : nullptr);
      if (!mode.single) c.tally->add(o);
      const bool ok = o.success && pose_within(o.pose, frame.cam_from_world, c.options.thresholds);
      if (mode.tracking_radius > 0.0) tracking.add(o, ok);
      correct += ok;
      trusted += o.localized;
      trusted_correct += o.localized && ok;
      cpu.push_back(o.cpu_ms);
      wall.push_back(o.wall_ms);
      selected += o.selected;
      scored += static_cast<double>(o.scored.size());
      loaded += o.loaded;
      localized += o.success;
      ++runs;
      if (o.success && s == 0) pos_err.push_back(position_error(o.pose, frame.cam_from_world));
      if (s == 0) jframes.push_back(frame_json(frame, mode, o, ok));
      progress(s, false);
    }
    correct_per_seed.push_back(correct);
    trusted_per_seed.push_back(trusted);
    trusted_correct_per_seed.push_back(trusted_correct);
    progress(s, true);
  }
  const double nf = static_cast<double>(frames.size());
  const double recall = std::accumulate(correct_per_seed.begin(), correct_per_seed.end(), 0.0) / (nf * c.options.seeds);
  const double n = static_cast<double>(runs);
  nlohmann::json jm = {
      {"mode", mode.name},
      {"pose_recall", recall},
      {"frames_correct_per_seed", correct_per_seed},
      // The frames reported localized (the answer to act on: a calibrated
      // confidence at its operating point) and of them correct, per seed.
      {"localized_frames_per_seed", trusted_per_seed},
      {"localized_correct_per_seed", trusted_correct_per_seed},
      {"localized_per_frame", localized / n},
      {"median_position_error_m", median(pos_err)},
      {"cpu_ms_per_frame", {{"mean", mean(cpu)}, {"median", median(cpu)}, {"p95", quantile(cpu, 0.95)}}},
      {"wall_ms_per_frame", {{"mean", mean(wall)}, {"median", median(wall)}, {"p95", quantile(wall, 0.95)}}}};
  if (mode.has_prior) jm["prior_noise_m"] = mode.noise;
  std::string areas_text = "-";
  if (!mode.single) {
    jm["areas_selected_per_frame"] = selected / n;
    jm["areas_scored_per_frame"] = scored / n;
    jm["areas_loaded_per_frame"] = loaded / n;
    if (mode.tracking_radius > 0.0) {
      jm["tracking_radius_m"] = mode.tracking_radius;
      jm["tracking_areas"] = c.options.tracking_areas;
      if (c.options.track_prior_noise >= 0.0) jm["relocalization_prior_noise_m"] = c.options.track_prior_noise;
      tracking.report(n, &jm);
    }
    jm["area_loads"] = c.bundle->loads() - loads_before;
    jm["areas_loaded_at_end"] = c.bundle->loaded_ids().size();
    jm["loaded_bytes_at_end"] = c.bundle->loaded_bytes();
    areas_text = number_text(selected / n) + " / " + number_text(scored / n) + " / " + number_text(loaded / n);
    if (mode.tracking_radius > 0.0) areas_text += tracking.text();
  }
  jm["frames"] = std::move(jframes);
  std::string seeds_text;
  for (size_t i = 0; i < correct_per_seed.size(); ++i) {
    if (i > 0) seeds_text += ',';
    seeds_text += std::to_string(correct_per_seed[i]);
  }
  const int trusted = std::accumulate(trusted_per_seed.begin(), trusted_per_seed.end(), 0);
  const int trusted_right = std::accumulate(trusted_correct_per_seed.begin(), trusted_correct_per_seed.end(), 0);
  const std::string trusted_text = std::to_string(trusted) + " (" + std::to_string(trusted_right) + " right)";
  char line[400];
  std::snprintf(line, sizeof(line), "%-17s  %6.4f  (%s of %zu)  %9.3f  %-16s %9.3f  %8.2f %8.2f  %s\n",
                mode.name.c_str(), recall, seeds_text.c_str(), frames.size(), localized / n, trusted_text.c_str(),
                median(pos_err), mean(cpu), median(cpu), areas_text.c_str());
  *table += line;
  return jm;
}

}  // namespace

BundleEvalResult evaluate_bundle(const BundleEvalOptions& options) {
  options.check();
  const std::shared_ptr<AreaBundle> bundle = AreaBundle::open(options.bundle);
  const LandmarkMap map = read_map_h5(options.map);
  std::vector<frame_t> frames;
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    if (map.frames[f].is_query) frames.push_back(f);
  }
  // Capture order (frame names: session/file), which tracking follows.
  std::stable_sort(frames.begin(), frames.end(),
                   [&](frame_t a, frame_t b) { return map.frames[a].name < map.frames[b].name; });
  LMB_CHECK(!frames.empty(), options.map << ": no query frames");
  // The bundle, its areas and the single model must be of this map: another map's would pose every
  // frame somewhere else without a word.
  const uint64_t map_fingerprint = fingerprint_map(map);
  if (bundle->map_fingerprint() != 0) {
    LMB_CHECK(bundle->map_fingerprint() == map_fingerprint,
              options.bundle << ": the bundle was made for another map than " << options.map << " (map fingerprints "
                             << hex_text(bundle->map_fingerprint()) << " and " << hex_text(map_fingerprint) << ")");
  }
  bundle->set_model_transform([&map, &options](int32_t, std::shared_ptr<const Model> model) {
    check_model_fits_map(*model, "the area's model", map, options.map);
    return model;
  });
  std::shared_ptr<const Model> single;
  if (!options.model.empty()) {
    single = Model::load(options.model);
    check_model_fits_map(*single, options.model, map, options.map);
  }

  nlohmann::json report;
  report["bundle"] = options.bundle;
  report["map"] = options.map;
  report["model"] = options.model;
  report["frames"] = frames.size();
  report["seeds"] = options.seeds;
  report["first_seed"] = options.localizer.pose.seed;
  report["prior_seed"] = options.prior_seed;
  report["area_search"] = options.search == AreaSearch::kAll           ? "all"
                          : options.search == AreaSearch::kWinnersView ? "winners_view"
                                                                       : "nearest_first";
  report["area_winner"] = options.winner == AreaWinner::kSupport ? "support" : "inliers";
  report["area_threads"] = options.area_threads;
  report["tracking_areas"] = options.tracking_areas;
  report["reach_m"] = bundle->reach();
  // The bundle's calibrations: what `localized` means in each mode (docs/areas.md).
  report["calibration"] = {
      {"calibrated", bundle->calibrated()},
      {"saw_wrong_pose", bundle->calibrated() && !bundle->calibration().saw_no_wrong_pose()},
      {"walk_calibrated", bundle->walk_calibration().has_value()},
      {"walk_rule", bundle->walk_calibration() && bundle->walk_calibration()->adds},
      {"walk_agreement", bundle->walk_calibration() && bundle->walk_calibration()->has_agreement()}};
  if (!bundle->calibrated()) {
    spdlog::info("eval --bundle: an uncalibrated bundle: an area's own calibrated verdict is its answer");
  } else if (bundle->calibration().saw_no_wrong_pose()) {
    spdlog::warn("eval --bundle: the bundle's calibration saw no wrong pose: every winning pose is reported{}",
                 bundle->walk_calibration() ? "; tracking's walk agreement still refuses a pose" : "");
  }
  report["thresholds"] = {{"position_m", options.thresholds.max_position_error_m},
                          {"rotation_deg", options.thresholds.max_rotation_error_deg}};
  report["cache"] = {{"max_areas", options.cache.max_areas}, {"max_bytes", options.cache.max_bytes}};
  report["areas"] = measure_areas(*bundle, options.memory_per_area);
  bundle->set_cache_limits(options.cache);

  BundleEvalResult result;
  result.table =
      "mode               recall  (per seed)              posed  localized (all seeds)  med_pos_m  cpu_ms/frame "
      "(mean, median)  areas selected/scored/loaded per frame\n";
  AreaTally tally;
  const ModeContext context{options, map, bundle, single, &tally};
  nlohmann::json jmodes = nlohmann::json::array();
  for (const Mode& mode : make_modes(options, single != nullptr)) {
    jmodes.push_back(evaluate_mode(context, mode, frames, &result.table));
  }
  bundle->set_model_transform({});
  // Not one frame could be scored because no area loads: an error, not a table of zeros.
  LMB_CHECK(tally.errors.empty() || tally.scored_runs > 0,
            options.bundle << ": no area could be loaded (" << tally.errors.size()
                           << " area error(s); the first: " << tally.errors.begin()->first << ")");
  nlohmann::json jerrors = nlohmann::json::array();
  for (const auto& [line, runs] : tally.errors) {
    result.area_errors.push_back(line);
    jerrors.push_back({{"error", line}, {"frame_runs", runs}});
  }
  report["area_errors"] = std::move(jerrors);
  report["modes"] = std::move(jmodes);
  result.report = std::move(report);
  return result;
}

}  // namespace lmb
