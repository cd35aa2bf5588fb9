// `lboost localize`: model.lbm + the query frames of a map (keypoints, descriptors, camera and
// gravity as the mapper detected them) -> poses and matches as JSON, and a summary against the
// map's ground-truth poses and keypoint landmarks. With --bundle (docs/areas.md): the query frames
// localized through a bundle of area models, with a noisy ground-truth prior and/or none. With
// --image/--images instead of --map: photos, detected as the mapper detects map images, localized
// with a given camera and gravity (train/cli/photo_localization.h, docs/localize_photos.md).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/gravity_file.h"
#include "common/io/map_h5.h"
#include "common/landmark_map.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "train/cli/bundle_mode_options.h"
#include "train/cli/commands.h"
#include "train/cli/photo_localization.h"
#include "train/eval/bundle_eval.h"
#include "train/eval/evaluation.h"
#include "train/eval/map_localization.h"

namespace lmb::cli {

namespace {

struct LocalizeArgs {
  std::string model;
  std::string map;
  std::vector<std::string> queries;  // frame names; empty = every query frame
  std::string out;
  LocalizerOptions options;
  int threads = 1;
  bool all_matches = false;
  BundleEvalOptions bundle;  // --bundle, --prior-noise, --no-prior, --prior-seed, --cache-areas
  // Photos (instead of --map): --image files or the photos of an --images folder.
  std::vector<std::string> images;
  std::string images_dir;
  std::string camera;                             // "MODEL WIDTH HEIGHT PARAMS..."
  std::vector<double> gravity;                    // GX GY GZ, every photo
  std::string gravity_file;                       // IMAGE_NAME GX GY GZ per photo
  std::vector<double> prior;                      // X Y Z RADIUS (--bundle)
  DetectorOptions detector;                       // --max-keypoints; the detector is the model's
  std::vector<const CLI::Option*> photo_options;  // the options only photos take
};

// The detector of the model, or of the first area of the bundle that loads (a bundle's areas share
// their descriptors).
std::string model_detector(const Model* model, AreaBundle* bundle) {
  if (model != nullptr) return model->data().detector;
  std::string first_error;
  for (const BundleArea& area : bundle->areas()) {
    try {
      return bundle->model(area.id)->data().detector;
    } catch (const Error& e) {
      if (first_error.empty()) first_error = e.what();
    }
  }
  LMB_FAIL("--bundle " << bundle->index_path().string() << ": no area model could be loaded: " << first_error);
}

// The photo mode's settings from the command line: camera, gravity, prior, detector.
PhotoLocalizationOptions photo_settings(const LocalizeArgs& a) {
  PhotoLocalizationOptions o;
  o.camera = camera_from_text(a.camera, "--camera");
  if (!a.gravity_file.empty()) {
    o.gravity_by_name = read_gravity_file(a.gravity_file);
    o.gravity_file = a.gravity_file;
  } else if (!a.gravity.empty()) {
    o.gravity_in_cam = Eigen::Vector3d(a.gravity[0], a.gravity[1], a.gravity[2]);
    LMB_CHECK(o.gravity_in_cam.allFinite() && o.gravity_in_cam.norm() > 0,
              "--gravity " << a.gravity[0] << " " << a.gravity[1] << " " << a.gravity[2]
                           << ": must be a finite, non-zero direction");
  }
  if (!a.prior.empty()) {
    PositionPrior prior;
    prior.position = Eigen::Vector3d(a.prior[0], a.prior[1], a.prior[2]);
    prior.radius = a.prior[3];
    prior.check();
    o.prior = prior;
  }
  o.detector = a.detector;
  o.threads = a.threads;
  return o;
}

// --image/--images: the photos through the model, or through the bundle.
void run_photo_localize(const LocalizeArgs& a) {
  LMB_CHECK(a.map.empty(), "--image/--images and --map are exclusive: photos, or the query frames of a map");
  LMB_CHECK(a.images.empty() || a.images_dir.empty(), "give --image or --images, not both");
  LMB_CHECK(!a.camera.empty(),
            "--image/--images needs --camera \"MODEL WIDTH HEIGHT PARAMS...\" (COLMAP cameras.txt, e.g. \"PINHOLE 640 "
            "480 fx fy cx cy\"): the camera is not read from the photos");
  LMB_CHECK(a.queries.empty() && a.bundle.prior_noise.empty() && !a.bundle.no_prior && a.bundle.track.empty() &&
                !a.all_matches,
            "--queries, --prior-noise, --no-prior, --track and --all-matches need --map");
  LMB_CHECK(a.model.empty() != a.bundle.bundle.empty(), "photos: give --model or --bundle (one of them)");
  LMB_CHECK(a.prior.empty() || !a.bundle.bundle.empty(), "--prior needs --bundle");
  LMB_CHECK(a.gravity.empty() || a.gravity_file.empty(), "give --gravity or --gravity-file, not both");
  std::vector<std::filesystem::path> photos;
  std::vector<NamedPath> inputs = bundle_input_paths(a.bundle.bundle, "--bundle");
  if (!a.images_dir.empty()) {
    photos = list_photos(a.images_dir);
    inputs.push_back({a.images_dir, "--images", true});
  }
  for (const std::string& image : a.images) {
    photos.emplace_back(image);
    inputs.push_back({image, "--image"});
  }
  inputs.push_back({a.model, "--model"});
  inputs.push_back({a.gravity_file, "--gravity-file"});
  check_outputs_not_inputs({{a.out, "--out"}}, inputs);
  check_writable_file(a.out, "--out");
  PhotoLocalizationOptions o = photo_settings(a);
  std::shared_ptr<const Model> model;
  std::shared_ptr<AreaBundle> bundle;
  if (!a.model.empty()) {
    model = Model::load(a.model);
  } else {
    bundle = AreaBundle::open(a.bundle.bundle);
    bundle->set_cache_limits(a.bundle.cache);
  }
  o.detector.detector = model_detector(model.get(), bundle.get());
  const int32_t bytes = model ? model->descriptor_bytes() : bundle->descriptor_bytes();
  LMB_CHECK(detector_descriptor_bytes(o.detector.detector) == bytes,
            "the model's detector " << o.detector.detector << " gives "
                                    << detector_descriptor_bytes(o.detector.detector)
                                    << "-byte descriptors, the model reads " << bytes);
  nlohmann::json out;
  if (model) {
    const Localizer localizer(model, a.options);
    out = localize_photos(photos, &localizer, nullptr, o);
    out["model"] = a.model;
  } else {
    BundleLocalizerOptions bo;
    bo.localizer = a.options;
    bo.search = a.bundle.search;
    bo.winner = a.bundle.winner;
    bo.area_threads = a.bundle.area_threads;
    const BundleLocalizer localizer(bundle, bo);
    out = localize_photos(photos, nullptr, &localizer, o);
    out["bundle"] = a.bundle.bundle;
  }
  write_file_atomically(a.out, out.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  std::printf("%s -> %s\n", photo_localization_summary_line(out.at("summary"), a.threads).c_str(), a.out.c_str());
}

// --bundle: every query frame through the bundle in each prior mode (one RANSAC seed, one thread).
void run_bundle_localize(const LocalizeArgs& a) {
  LMB_CHECK(a.queries.empty(), "localize: --queries is not supported with --bundle (every query frame)");
  check_writable_file(a.out, "--out");
  BundleEvalOptions b = a.bundle;
  b.map = a.map;
  b.model = a.model;
  b.localizer = a.options;
  b.seeds = 1;
  b.memory_per_area = false;
  const BundleEvalResult r = evaluate_bundle(b);
  write_file_atomically(a.out, r.report.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  warn_area_errors("localize", r.area_errors);
  std::printf("localize: bundle %s, %zu query frames, seed %llu, correct within 0.2 m / 5 deg:\n%s-> %s\n",
              b.bundle.c_str(), r.report.at("frames").get<size_t>(),
              static_cast<unsigned long long>(a.options.pose.seed), r.table.c_str(), a.out.c_str());
}

void run_localize(const LocalizeArgs& a) {
  if (!a.images.empty() || !a.images_dir.empty()) {
    run_photo_localize(a);
    return;
  }
  LMB_CHECK(!a.map.empty(), "give --map (the query frames of a map) or --image/--images (photos)");
  for (const CLI::Option* option : a.photo_options) {
    LMB_CHECK(option->count() == 0, option->get_name() << " is for photos: give --image or --images");
  }
  std::vector<NamedPath> inputs = bundle_input_paths(a.bundle.bundle, "--bundle");
  inputs.push_back({a.model, "--model"});
  inputs.push_back({a.map, "--map"});
  check_outputs_not_inputs({{a.out, "--out"}}, inputs);
  LMB_CHECK(a.threads >= 1 && a.threads <= 256, "localize: --threads = " << a.threads << " must be in 1..256");
  if (!a.bundle.bundle.empty()) {
    run_bundle_localize(a);
    return;
  }
  LMB_CHECK(a.bundle.prior_noise.empty() && !a.bundle.no_prior && a.bundle.track.empty(),
            "localize: --prior-noise, --track and --no-prior need --bundle");
  LMB_CHECK(!a.model.empty(), "localize: --model is required (or --bundle)");
  check_writable_file(a.out, "--out");
  const std::shared_ptr<const Model> model = Model::load(a.model);
  const LandmarkMap map = read_map_h5(a.map);
  const std::vector<char> is_class = check_model_fits_map(*model, a.model, map, a.map);
  MapLocalizationOptions o;
  o.localizer = a.options;
  o.queries = a.queries;
  o.threads = a.threads;
  o.all_matches = a.all_matches;
  nlohmann::json out = localize_map_frames(model, map, is_class, o);
  out["model"] = a.model;
  out["map"] = a.map;
  write_file_atomically(a.out, out.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  std::printf("%s -> %s\n", map_localization_summary_line(out.at("summary"), a.threads).c_str(), a.out.c_str());
}

// The options of the photo mode (--image/--images); those only photos take are recorded in
// args->photo_options.
void add_photo_options(CLI::App* cmd, LocalizeArgs* args) {
  cmd->add_option("--image", args->images,
                  "Photos to localize instead of --map (image files OpenCV reads; each gets an entry of --out, in "
                  "this order)");
  cmd->add_option(
      "--images", args->images_dir,
      "Or a folder whose photos (png, jpg, jpeg, bmp, ppm, pgm, tif, tiff; not its sub-folders) are localized, "
      "sorted by name");
  const std::vector<CLI::Option*> only_photos = {
      cmd->add_option("--camera", args->camera,
                      "The photos' camera, required with --image/--images: \"MODEL WIDTH HEIGHT PARAMS...\" as a "
                      "line of COLMAP's cameras.txt without the id, e.g. \"PINHOLE 640 480 fx fy cx cy\" "
                      "(SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV)"),
      cmd->add_option("--gravity", args->gravity,
                      "Photos: gravity (down) in the camera frame (x right, y down, z forward), any length, for "
                      "every photo. Default 0 1 0: the camera upright and level; a tilted camera needs its own "
                      "gravity (an accelerometer's) or poses get worse")
          ->expected(3),
      cmd->add_option("--gravity-file", args->gravity_file,
                      "Photos: per-photo gravity, lines IMAGE_NAME GX GY GZ (the photo's file name; the format of "
                      "a collection's gravity.txt); every photo needs a line"),
      cmd->add_option("--prior", args->prior,
                      "Photos with --bundle: the camera is within RADIUS metres of X Y Z (world frame): only the "
                      "areas near it are scored (default: every area)")
          ->expected(4),
      cmd->add_option("--max-keypoints", args->detector.max_keypoints,
                      "Photos: keypoints per photo, the strongest (the map's `lboost map --max-keypoints`; the "
                      "detector is the model's)")
          ->capture_default_str()};
  args->photo_options.assign(only_photos.begin(), only_photos.end());
}

}  // namespace

void add_localize_command(CLI::App& app) {
  auto args = std::make_shared<LocalizeArgs>();
  auto* cmd = app.add_subcommand(
      "localize", "Localize the query frames of a map, or photos, with model.lbm or a bundle; write poses as JSON");
  cmd->add_option("--model", args->model,
                  "Inference model (model.lbm); with --bundle and --map, the single model compared");
  cmd->add_option("--bundle", args->bundle.bundle,
                  "A bundle of area models (bundle.txt of `lboost bundle`): with --map localized with --prior-noise "
                  "and/or --no-prior, photos with --prior or in every area");
  add_bundle_mode_options(cmd, &args->bundle);
  cmd->add_option("--map", args->map, "Map whose query frames are localized (map.h5)");
  cmd->add_option("--queries", args->queries, "Frame names to localize (default: every query frame)");
  add_photo_options(cmd, args.get());
  cmd->add_option("--out", args->out, "Output JSON (poses, matches, summary)")->required();
  cmd->add_option("--top-k", args->options.classifier.top_k, "Matches kept per keypoint")->capture_default_str();
  cmd->add_flag("--inverted-file", args->options.classifier.use_inverted_file,
                "Score only the keypoint word's candidate classes");
  cmd->add_option("--inverted-file-words", args->options.classifier.inverted_file_words,
                  "--inverted-file: the candidates of the keypoint's N nearest words (1 = its own word; 2 = "
                  "multiple assignment)")
      ->capture_default_str();
  cmd->add_option("--min-margin", args->options.classifier.min_margin,
                  "Background rejection: a match must beat the background's score by more than this "
                  "(-inf = no rejection)")
      ->capture_default_str();
  cmd->add_option("--pose-top-k", args->options.pose_top_k, "Matches per keypoint fed to RANSAC")
      ->capture_default_str();
  cmd->add_option("--max-correspondences", args->options.max_correspondences,
                  "Best-margin matches fed to RANSAC (0 = all)")
      ->capture_default_str();
  cmd->add_option("--ransac-iterations", args->options.pose.max_iterations, "RANSAC iterations")->capture_default_str();
  cmd->add_option("--max-error", args->options.pose.max_reprojection_error_px, "Inlier threshold, pixels")
      ->capture_default_str();
  cmd->add_option("--min-inliers", args->options.pose.min_inliers, "Inliers for a pose")->capture_default_str();
  cmd->add_option("--min-confidence", args->options.min_confidence,
                  "Calibrated probability a pose needs to count as localized (negative: the model's operating "
                  "point; ignored by an uncalibrated model)")
      ->capture_default_str();
  add_seed_option(cmd, "--seed", &args->options.pose.seed, "RANSAC seed");
  cmd->add_flag("--uniform-sampling{false}", args->options.pose.progressive_sampling,
                "Uniform RANSAC sampling instead of PROSAC in the order of the match margins");
  cmd->add_option("--threads", args->threads, "Frames or photos localized in parallel")->capture_default_str();
  cmd->add_flag("--all-matches", args->all_matches, "Write every ranked match, not only the pose's");
  cmd->callback([args] { run_localize(*args); });
}

}  // namespace lmb::cli
