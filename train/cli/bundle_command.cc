// lboost bundle: the index (bundle.txt) of a bundle of area models (infer/area_bundle.h,
// docs/areas.md) from the areas file and the areas' exported models.
//   lboost bundle --areas areas.txt --models DIR [--out DIR/bundle.txt]
// DIR holds area-ID.lbm for every area of the file (lboost export of each area's run); each must
// be a valid model whose classes are exactly its area's landmarks. With --map (the map the areas
// split), the bundle's pose calibration is fitted on map frames and written into the index.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/feature_space.h"
#include "common/file_container.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "infer/area_bundle.h"
#include "infer/model.h"
#include "infer/pose_confidence.h"
#include "train/areas/area_file.h"
#include "train/cli/commands.h"
#include "train/eval/bundle_eval.h"
#include "train/eval/landmarkboost_matcher.h"
#include "train/eval/metrics.h"
#include "train/eval/pose_calibration_fit.h"

namespace lmb::cli {

namespace {

struct BundleArgs {
  std::string areas;
  std::string models;
  std::string out;
  std::string map;               // optional: fit the bundle's calibration on its map frames
  int calibration_frames = 100;  // at most this many map frames
  bool inverted_file = false;    // localize them with the inverted file
  uint64_t seed = 0;             // RANSAC seed
  double target_precision = 0.95;
};

// The bundle's pose calibration (infer/area_bundle.h, BundleLocalizeResult::evidence), fitted on
// the frames the areas' training held out (default training options; calibration_holdout_frames), else on
// map frames (train/eval/pose_calibration_fit.h, calibration_frames: every s-th frame of the map
// sessions) the way `lboost export` fits a model's, with the support rule and the areas' descriptor
// fusion without the frames' own exemplars; a pose is right within
// 0.2 m / 5 deg of the frame's map pose. Each frame twice: localized in every area (no prior: the
// most areas compete), and "elsewhere", in every area that holds no landmark in its view
// (landmarks_in_view), i.e. the frame as if taken where the map holds only look-alikes: a map
// frame's own areas rarely give a wrong pose, the elsewhere variant gives the wrong poses an
// aliased place gives. Operating point: the higher of the target precision's and the one that
// lets at most 1% of the frames' elsewhere variants pass. No query frame is read. Returns false
// (and prints why) when too few right or wrong poses were found to fit one.
bool fit_bundle_calibration(const BundleArgs& args, const std::filesystem::path& index, const AreaFile& file,
                            PoseCalibration* out) {
  const LandmarkMap map = read_map_h5(args.map);
  LMB_CHECK(fingerprint_map(map) == file.map_fingerprint,
            "--map " << args.map << " is not the map " << args.areas << " splits (fingerprints differ)");
  // The frames the areas' training held out (default training options), else every n-th map frame.
  PoseCalibrationOptions frame_options;
  frame_options.max_frames = args.calibration_frames;
  frame_options = with_holdout_frames(frame_options, map, TrainingSetOptions{});
  const std::vector<frame_t> frames = calibration_frames(map, frame_options);
  const auto bundle = AreaBundle::open(index);
  // The areas' descriptor fusion without the frames' own descriptors among its exemplars (else each
  // keypoint finds itself at distance 0), as `lboost export` fits a model's calibration.
  const std::vector<int64_t> own = calibration_frame_keypoints(map, frames);
  const auto rows = [](const Model& m) {
    return m.data().fusion.enabled() ? m.data().fusion.exemplar_begin.back() : int64_t{0};
  };
  std::vector<int64_t> file_rows(bundle->areas().size(), -1);  // per area: its file's exemplars (once loaded)
  bundle->set_model_transform([&](int32_t id, std::shared_ptr<const Model> model) {
    file_rows[static_cast<size_t>(id)] = rows(*model);
    return without_exemplars(model, map, own, /*keep_sole=*/true);
  });
  LocalizerOptions lo;
  lo.classifier.use_inverted_file = args.inverted_file;
  lo.pose.seed = args.seed;
  const PoseThresholds thresholds;
  std::vector<PoseEvidence> evidence;
  std::vector<char> right, elsewhere;
  const auto started = std::chrono::steady_clock::now();
  auto last_line = started;
  for (size_t i = 0; i < frames.size(); ++i) {
    const MapFrame& frame = map.frames[frames[i]];
    const std::vector<Keypoint> keypoints(map.keypoints.begin() + frame.first_keypoint,
                                          map.keypoints.begin() + frame.first_keypoint + frame.num_keypoints);
    const std::vector<char> view = landmarks_in_view(map, frames[i]);
    std::vector<int32_t> all, away;
    for (const Area& area : file.split.areas) {
      all.push_back(area.id);
      const bool sees = std::any_of(area.landmarks.begin(), area.landmarks.end(), [&](landmark_t l) {
        return l >= 0 && static_cast<size_t>(l) < view.size() && view[static_cast<size_t>(l)] != 0;
      });
      if (!sees) away.push_back(area.id);
    }
    for (int variant = 0; variant < 2; ++variant) {
      const std::vector<int32_t>& ids = variant == 0 ? all : away;
      if (ids.empty()) continue;
      const BundleLocalizeResult r =
          localize_in_areas(*bundle, ids, map.cameras[frame.camera], keypoints, map.descriptor(frame.first_keypoint),
                            frame.gravity_in_cam, lo, AreaWinner::kSupport);
      LMB_CHECK(r.errors.empty(), "bundle calibration: " << r.errors.front());
      if (r.area < 0) continue;
      evidence.push_back(r.evidence);
      right.push_back(pose_within(r.result.pose.cam_from_world, frame.cam_from_world, thresholds) ? 1 : 0);
      elsewhere.push_back(static_cast<char>(variant));
    }
    const auto now = std::chrono::steady_clock::now();
    if (now - last_line >= std::chrono::seconds(30) || i + 1 == frames.size()) {
      last_line = now;
      const double elapsed = std::chrono::duration<double>(now - started).count();
      spdlog::info("bundle: calibration frame {} of {}, {:.0f} s, ETA {:.0f} s", i + 1, frames.size(), elapsed,
                   elapsed * static_cast<double>(frames.size() - i - 1) / static_cast<double>(i + 1));
    }
  }
  // The exemplars the calibration's models left out, counted on the models the bundle scored.
  int64_t exemplars = 0, left_out = 0;
  for (size_t id = 0; id < file_rows.size(); ++id) {
    if (file_rows[id] < 0) continue;
    exemplars += file_rows[id];
    left_out += file_rows[id] - rows(*bundle->model(static_cast<int32_t>(id)));
  }
  const int64_t num_right = std::count(right.begin(), right.end(), 1);
  const int64_t num_wrong = static_cast<int64_t>(right.size()) - num_right;
  if (num_right < 5 || num_wrong < 5) {
    spdlog::warn(
        "bundle: no calibration: {} map frames gave {} poses, {} right and {} wrong (at least 5 of each "
        "are needed); the index is written without one",
        frames.size(), right.size(), num_right, num_wrong);
    return false;
  }
  PoseCalibration c = fit_pose_calibration(evidence, right);
  std::vector<double> p;
  for (const PoseEvidence& e : evidence) p.push_back(c.probability(e));
  const double for_precision = precision_threshold(p, right, args.target_precision);
  std::vector<double> p_elsewhere;
  for (size_t i = 0; i < p.size(); ++i) {
    if (elsewhere[i]) p_elsewhere.push_back(p[i]);
  }
  const double for_elsewhere = pass_share_threshold(p_elsewhere, static_cast<int64_t>(frames.size()), 0.01);
  c.threshold = std::max(for_precision, for_elsewhere);
  c.target_precision = args.target_precision;
  c.check("bundle calibration");
  int64_t kept = 0, kept_right = 0, kept_elsewhere = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    kept += p[i] >= c.threshold;
    kept_right += p[i] >= c.threshold && right[i];
    kept_elsewhere += p[i] >= c.threshold && elsewhere[i];
  }
  spdlog::info(
      "bundle: calibration on {} map frames{}: {} poses ({} of them elsewhere), {} right; the areas' fusion "
      "without the frames' own {} of {} exemplars; operating point {:.4f} (precision {}: {:.4f}; at most 1% of the "
      "frames elsewhere: {:.4f}) keeps {} poses, {} right, {} of them elsewhere",
      frames.size(),
      frame_options.frames.empty() ? " (the default training options hold none out)"
                                   : " (the ones the default training options hold out of training)",
      right.size(), p_elsewhere.size(), num_right, left_out, exemplars, c.threshold, args.target_precision,
      for_precision, for_elsewhere, kept, kept_right, kept_elsewhere);
  *out = c;
  return true;
}

void run_bundle(const BundleArgs& args) {
  namespace fs = std::filesystem;
  const fs::path dir(args.models);
  const fs::path out = args.out.empty() ? dir / "bundle.txt" : fs::path(args.out);
  LMB_CHECK(fs::weakly_canonical(out.parent_path()) == fs::weakly_canonical(dir),
            "--out " << out.string() << ": the index must sit in the --models folder " << dir.string()
                     << " (its model file names are relative to it)");
  check_writable_file(out, "--out");
  const AreaFile file = read_area_file(args.areas);
  std::vector<BundleArea> areas;
  uint64_t total = 0;
  for (const Area& area : file.split.areas) {
    BundleArea a;
    a.id = area.id;
    a.file = "area-" + std::to_string(area.id) + ".lbm";
    const fs::path path = dir / a.file;
    const std::string what = path.string() + " (area " + std::to_string(area.id) + ")";
    std::string image;
    try {
      image = read_file(path);
    } catch (const Error& e) {
      LMB_FAIL("area " << area.id << ": " << e.what() << " (export the area's run there first)");
    }
    const auto model = Model::from_bytes(reinterpret_cast<const uint8_t*>(image.data()), image.size(), what);
    LMB_CHECK(model->num_classes() == static_cast<int32_t>(area.landmarks.size()),
              what << ": " << model->num_classes() << " classes, the area has " << area.landmarks.size()
                   << " landmarks (a model of another area or split?)");
    for (int32_t c = 0; c < model->num_classes(); ++c) {
      LMB_CHECK(model->class_landmark(c) == area.landmarks[static_cast<size_t>(c)],
                what << ": class " << c << " is landmark " << model->class_landmark(c) << ", the area's is "
                     << area.landmarks[static_cast<size_t>(c)] << " (a model of another area or split?)");
    }
    a.bytes = image.size();
    a.crc32 = crc32(reinterpret_cast<const uint8_t*>(image.data()), image.size());
    a.landmarks = static_cast<int64_t>(area.landmarks.size());
    a.cell_lo = area.cell.lo;
    a.cell_hi = area.cell.hi;
    total += a.bytes;
    areas.push_back(a);
  }
  write_bundle_index(out, file.split.options.reach, areas);
  PoseCalibration calibration;
  if (!args.map.empty() && args.calibration_frames > 0 && fit_bundle_calibration(args, out, file, &calibration)) {
    write_bundle_index(out, file.split.options.reach, areas, &calibration);
  }
  std::printf("bundle: %zu areas, %.1f MB of models, reach %.2f m -> %s\n", areas.size(),
              static_cast<double>(total) / 1048576.0, file.split.options.reach, out.string().c_str());
}

}  // namespace

void add_bundle_command(CLI::App& app) {
  auto args = std::make_shared<BundleArgs>();
  auto* cmd = app.add_subcommand("bundle", "Index the areas' exported models as a bundle (docs/areas.md)");
  cmd->add_option("--areas", args->areas, "areas file (lboost areas)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--models", args->models, "folder with area-ID.lbm for every area (lboost export)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", args->out, "the index, in the --models folder (default MODELS/bundle.txt)");
  cmd->add_option("--map", args->map,
                  "the map the areas split (map.h5): fit the bundle's pose calibration on its map frames")
      ->check(CLI::ExistingFile);
  cmd->add_option("--calibration-frames", args->calibration_frames,
                  "--map: map frames localized for the calibration at most (0 = no calibration)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--inverted-file", args->inverted_file,
                "--map: localize the calibration frames with the inverted file (as the bundle will be used)");
  cmd->add_option("--seed", args->seed, "--map: RANSAC seed of the calibration frames")->capture_default_str();
  cmd->add_option("--target-precision", args->target_precision,
                  "--map: the operating point's precision on the calibration poses")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 1.0));
  cmd->callback([args] { run_bundle(*args); });
}

void add_bundle_mode_options(CLI::App* cmd, BundleEvalOptions* options) {
  cmd->add_option("--prior-noise", options->prior_noise,
                  "--bundle: a position prior per query frame, its true centre moved METRES in a seeded direction, "
                  "radius METRES (repeatable)");
  cmd->add_flag("--no-prior", options->no_prior, "--bundle: localize in every area, without a prior");
  cmd->add_option("--track", options->track,
                  "--bundle: track the query frames in capture order, the camera moving at most METRES a frame "
                  "(BundleLocalizer::track; repeatable)");
  cmd->add_option("--track-prior-noise", options->track_prior_noise,
                  "--bundle --track: relocalize with a position prior of this noise (as --prior-noise) instead of "
                  "in every area (negative: every area)")
      ->capture_default_str();
  cmd->add_option("--tracking-areas", options->tracking_areas,
                  "--bundle --track: areas scored before the motion gate judges the winning pose")
      ->capture_default_str();
  cmd->add_flag_function(
      "--all-areas", [options](int64_t) { options->search = AreaSearch::kAll; },
      "--bundle: with a prior, score every selected area (default: nearest area first, the first calibrated "
      "localized pose wins)");
  cmd->add_flag_function(
      "--winners-view", [options](int64_t) { options->search = AreaSearch::kWinnersView; },
      "--bundle: with a prior, nearest area first, then the areas that see most of the current winning pose's "
      "view (AreaSearch::kWinnersView: fewer areas before the calibrated stop)");
  cmd->add_option("--area-winner", options->winner,
                  "--bundle: which scored area's pose wins: support (explains most keypoints with every scored "
                  "area's matches) or inliers (most inliers of its own area)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, AreaWinner>{{"support", AreaWinner::kSupport}, {"inliers", AreaWinner::kInliers}}))
      ->default_str("support");
  cmd->add_option("--area-threads", options->area_threads,
                  "--bundle: areas of a frame localized at once, each on its own thread (the same result; "
                  "cpu_ms then counts the calling thread only: read wall_ms)")
      ->capture_default_str();
  cmd->add_option("--prior-seed", options->prior_seed, "--bundle: seed of the prior's direction")
      ->capture_default_str();
  cmd->add_option("--cache-areas", options->cache.max_areas,
                  "--bundle: at most this many areas loaded (least recently used freed first; 0 = no limit)")
      ->capture_default_str();
}

}  // namespace lmb::cli
