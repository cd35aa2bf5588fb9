#include "train/cli/photo_localization.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <exception>
#include <fstream>
#include <system_error>
#include <thread>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "train/cli/cli_util.h"
#include "train/eval/map_localization.h"
#include "train/eval/report.h"
#include "train/eval/timing.h"
#include "train/mapping/keypoint_detection.h"

namespace lmb::cli {

namespace fs = std::filesystem;

namespace {

// What one photo gave.
struct PhotoOutcome {
  std::string error;  // the photo could not be read (nothing else is set)
  int32_t num_keypoints = 0;
  Eigen::Vector3d gravity_in_cam = kUprightGravityInCam;
  double read_ms = 0.0;
  double detection_ms = 0.0;
  double total_ms = 0.0;   // read + detection + localization
  LocalizeResult result;   // the single model's, or the winning area's (empty without a winner)
  bool localized = false;  // the single model's or the bundle's verdict
  double confidence = -1.0;
  double localization_ms = 0.0;
  std::optional<BundleLocalizeResult> bundle;  // with a bundle: everything but `result`
};

// The photo as `lboost map` reads its images (OpenCV, grey; train/mapping/mapper.cc), or empty
// with the reason in `error`. Checked first for a file that cannot be opened: OpenCV would print
// a warning of its own.
cv::Mat read_photo(const fs::path& path, std::string* error) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec) || !std::ifstream(path).good()) {
    *error = path.string() + ": cannot read the image: no such file, or not a readable file";
    return cv::Mat();
  }
  cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
  if (image.empty()) *error = path.string() + ": cannot read the image: not a format OpenCV decodes";
  return image;
}

Eigen::Vector3d photo_gravity(const fs::path& path, const PhotoLocalizationOptions& o) {
  if (o.gravity_by_name.empty()) return o.gravity_in_cam;
  const auto it = o.gravity_by_name.find(path.filename().string());
  LMB_CHECK(it != o.gravity_by_name.end(),
            o.gravity_file << ": no gravity for photo " << path.filename().string() << " (" << path.string() << ")");
  return it->second;
}

PhotoOutcome localize_photo(const fs::path& path, const Localizer* localizer, const BundleLocalizer* bundle_localizer,
                            const PhotoLocalizationOptions& o) {
  PhotoOutcome out;
  const auto start = Clock::now();
  const cv::Mat image = read_photo(path, &out.error);
  out.read_ms = ms_since(start);
  if (!out.error.empty()) return out;
  const Camera& camera = o.camera;
  LMB_CHECK(image.cols == camera.width && image.rows == camera.height,
            path.string() << ": image is " << image.cols << "x" << image.rows << " pixels but --camera is "
                          << camera.width << "x" << camera.height);
  o.detector.check_image_size(image.cols, image.rows, path.string());
  out.gravity_in_cam = photo_gravity(path, o);
  const auto detect_start = Clock::now();
  const ImageFeatures features = detect_keypoints(image, o.detector);
  out.detection_ms = ms_since(detect_start);
  out.num_keypoints = static_cast<int32_t>(features.keypoints.size());
  const uint8_t* descriptors = features.descriptors.data();
  if (bundle_localizer != nullptr) {
    const PositionPrior* prior = o.prior ? &*o.prior : nullptr;
    BundleLocalizeResult b =
        bundle_localizer->localize(camera, features.keypoints, descriptors, out.gravity_in_cam, prior);
    out.result = std::move(b.result);
    out.localized = b.localized;
    out.confidence = b.confidence;
    out.localization_ms = b.total_ms;
    out.bundle = std::move(b);
  } else {
    out.result = localizer->localize(camera, features.keypoints, descriptors, out.gravity_in_cam);
    out.localized = out.result.localized;
    out.confidence = out.result.confidence;
    out.localization_ms = out.result.timings.total_ms;
  }
  out.total_ms = ms_since(start);
  return out;
}

// Every photo, `threads` at a time; the first error in photo order is thrown.
std::vector<PhotoOutcome> localize_all(const std::vector<fs::path>& photos, const Localizer* localizer,
                                       const BundleLocalizer* bundle_localizer, const PhotoLocalizationOptions& o) {
  std::vector<PhotoOutcome> outcomes(photos.size());
  std::vector<std::exception_ptr> errors(photos.size());
  std::atomic<size_t> next{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < o.threads; ++t) {
    pool.emplace_back([&] {
      for (size_t i = next++; i < photos.size(); i = next++) {
        try {
          outcomes[i] = localize_photo(photos[i], localizer, bundle_localizer, o);
        } catch (...) {
          errors[i] = std::current_exception();
        }
      }
    });
  }
  for (std::thread& t : pool) t.join();
  for (const std::exception_ptr& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  return outcomes;
}

nlohmann::json vector_json(const Eigen::Vector3d& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }

// The pose as `lboost localize --map` writes it ({qw, qx, qy, qz, tx, ty, tz}: x_cam = R x_world +
// t), the 3x4 matrix [R | t] by rows, and the camera centre in the world.
void write_pose(const Rigid3d& cam_from_world, nlohmann::json* jp) {
  (*jp)["cam_from_world"] = cam_from_world_json(cam_from_world);
  const Eigen::Vector3d& t = cam_from_world.translation;
  const Eigen::Matrix3d r = cam_from_world.rotation.toRotationMatrix();
  nlohmann::json m = nlohmann::json::array();
  for (int row = 0; row < 3; ++row) m.push_back({r(row, 0), r(row, 1), r(row, 2), t(row)});
  (*jp)["cam_from_world_matrix"] = std::move(m);
  (*jp)["camera_center"] = vector_json(cam_from_world.center());
}

nlohmann::json photo_json(const fs::path& path, const PhotoOutcome& o) {
  nlohmann::json jp;
  jp["path"] = path.string();
  if (!o.error.empty()) {
    jp["success"] = false;
    jp["error"] = o.error;
    return jp;
  }
  const LocalizeResult& r = o.result;
  // success: localized (the calibrated rule with a calibrated model or bundle, else the inlier
  // rule); pose_found: a pose with at least min-inliers inliers; confidence: the calibrated
  // probability (-1 uncalibrated).
  jp["success"] = o.localized;
  jp["pose_found"] = r.pose.success;
  jp["confidence"] = o.confidence;
  if (r.pose.success) write_pose(r.pose.cam_from_world, &jp);
  jp["num_inliers"] = r.pose.num_inliers;
  jp["num_correspondences"] = r.correspondence_keypoint.size();
  jp["num_keypoints"] = o.num_keypoints;
  jp["gravity_in_cam"] = vector_json(o.gravity_in_cam);
  if (o.bundle) {
    const BundleLocalizeResult& b = *o.bundle;
    jp["area"] = b.area;
    jp["areas_selected"] = b.selected;
    jp["areas_scored"] = b.scored.size();
    jp["scored"] = b.scored;
    if (!b.errors.empty()) jp["errors"] = b.errors;
    jp["timings_ms"] = {
        {"read", o.read_ms}, {"detection", o.detection_ms}, {"localization", o.localization_ms}, {"total", o.total_ms}};
  } else {
    jp["timings_ms"] = {{"read", o.read_ms},
                        {"detection", o.detection_ms},
                        {"embedding", r.timings.embedding_ms},
                        {"classification", r.timings.classification_ms},
                        {"pose", r.timings.pose_ms},
                        {"localization", o.localization_ms},
                        {"total", o.total_ms}};
  }
  return jp;
}

nlohmann::json summary_json(const std::vector<PhotoOutcome>& outcomes, bool calibrated) {
  int unreadable = 0, localized = 0, pose_found = 0;
  double read_ms = 0, detection_ms = 0, localization_ms = 0, total_ms = 0;
  for (const PhotoOutcome& o : outcomes) {
    if (!o.error.empty()) {
      ++unreadable;
      continue;
    }
    localized += o.localized;
    pose_found += o.result.pose.success;
    read_ms += o.read_ms;
    detection_ms += o.detection_ms;
    localization_ms += o.localization_ms;
    total_ms += o.total_ms;
  }
  const double n = std::max<double>(1.0, static_cast<double>(outcomes.size()) - unreadable);
  return {{"photos", outcomes.size()},
          {"unreadable", unreadable},
          {"calibrated", calibrated},
          {"localized", localized},
          {"pose_found", pose_found},
          {"ms_per_photo",
           {{"read", read_ms / n},
            {"detection", detection_ms / n},
            {"localization", localization_ms / n},
            {"total", total_ms / n}}}};
}

nlohmann::json options_json(const LocalizerOptions& o) {
  return {{"top_k", o.classifier.top_k},
          {"use_inverted_file", o.classifier.use_inverted_file},
          {"inverted_file_words", o.classifier.inverted_file_words},
          {"min_margin", json_number_or_string(o.classifier.min_margin)},
          {"pose_top_k", o.pose_top_k},
          {"max_correspondences", o.max_correspondences},
          {"ransac_iterations", o.pose.max_iterations},
          {"max_reprojection_error_px", o.pose.max_reprojection_error_px},
          {"min_inliers", o.pose.min_inliers},
          {"seed", o.pose.seed},
          {"prosac", o.pose.progressive_sampling}};
}

// The operating point applied: --min-confidence when >= 0, else the calibration's (null when
// uncalibrated).
nlohmann::json calibration_json(const PoseCalibration* calibration, double min_confidence) {
  if (calibration == nullptr) return nullptr;
  return {{"threshold", min_confidence >= 0 ? min_confidence : calibration->threshold},
          {"target_precision", calibration->target_precision}};
}

// OpenCV's own threads off while the photos are detected (as the mapper does: the parallelism is
// ours), restored afterwards.
class SingleThreadedOpenCv {
 public:
  SingleThreadedOpenCv() : previous_(cv::getNumThreads()) { cv::setNumThreads(1); }
  ~SingleThreadedOpenCv() { cv::setNumThreads(previous_); }
  SingleThreadedOpenCv(const SingleThreadedOpenCv&) = delete;
  SingleThreadedOpenCv& operator=(const SingleThreadedOpenCv&) = delete;

 private:
  int previous_;
};

}  // namespace

std::vector<fs::path> list_photos(const fs::path& dir) {
  std::error_code ec;
  LMB_CHECK(fs::is_directory(dir, ec), "--images " << dir.string() << ": not a folder");
  std::vector<fs::path> photos;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code type_ec;
    if (is_image_file(it->path()) && it->is_regular_file(type_ec)) photos.push_back(it->path());
  }
  LMB_CHECK(!ec, "--images " << dir.string() << ": cannot list the folder: " << ec.message());
  std::sort(photos.begin(), photos.end());
  LMB_CHECK(!photos.empty(), "--images " << dir.string() << ": no photos (" << kImageExtensions << ")");
  return photos;
}

nlohmann::json localize_photos(const std::vector<fs::path>& photos, const Localizer* localizer,
                               const BundleLocalizer* bundle_localizer, const PhotoLocalizationOptions& o) {
  LMB_CHECK(o.threads >= 1 && o.threads <= 256, "--threads = " << o.threads << " must be in 1..256");
  LMB_CHECK(localizer != nullptr || bundle_localizer != nullptr, "localize_photos: no localizer");
  o.camera.check("--camera");
  o.detector.check();
  const LocalizerOptions& lo = bundle_localizer ? bundle_localizer->options().localizer : localizer->options();
  std::vector<PhotoOutcome> outcomes;
  {
    SingleThreadedOpenCv opencv_threads;
    outcomes = localize_all(photos, localizer, bundle_localizer, o);
  }
  nlohmann::json out;
  out["camera"] = camera_to_text(o.camera);
  out["gravity"] = o.gravity_by_name.empty() ? nlohmann::json(vector_json(o.gravity_in_cam))
                                             : nlohmann::json({{"file", o.gravity_file}});
  out["prior"] = o.prior ? nlohmann::json({{"position", vector_json(o.prior->position)}, {"radius", o.prior->radius}})
                         : nlohmann::json(nullptr);
  out["detector"] = {{"detector", o.detector.detector},
                     {"max_keypoints", o.detector.max_keypoints},
                     {"brisk_threshold", o.detector.brisk_threshold},
                     {"brisk_octaves", o.detector.brisk_octaves}};
  out["options"] = options_json(lo);
  bool calibrated = false;
  if (bundle_localizer != nullptr) {
    calibrated = bundle_localizer->bundle().calibrated();
    out["calibration"] =
        calibration_json(calibrated ? &bundle_localizer->bundle().calibration() : nullptr, lo.min_confidence);
  } else {
    calibrated = localizer->model().calibrated();
    out["calibration"] = calibration_json(calibrated ? &localizer->model().calibration() : nullptr, lo.min_confidence);
  }
  nlohmann::json jphotos = nlohmann::json::array();
  for (size_t i = 0; i < photos.size(); ++i) jphotos.push_back(photo_json(photos[i], outcomes[i]));
  out["photos"] = std::move(jphotos);
  out["summary"] = summary_json(outcomes, calibrated);
  return out;
}

std::string photo_localization_summary_line(const nlohmann::json& s, int threads) {
  const nlohmann::json& ms = s.at("ms_per_photo");
  char line[512];
  std::snprintf(line, sizeof(line),
                "localize: %d/%zu photos localized (%s; %d with >= min-inliers inliers), %d unreadable; %.1f "
                "ms/photo (read %.1f, detection %.1f, localization %.1f, %d thread(s))",
                s.at("localized").get<int>(), s.at("photos").get<size_t>(),
                s.at("calibrated").get<bool>() ? "calibrated confidence" : "uncalibrated: inlier rule",
                s.at("pose_found").get<int>(), s.at("unreadable").get<int>(), ms.at("total").get<double>(),
                ms.at("read").get<double>(), ms.at("detection").get<double>(), ms.at("localization").get<double>(),
                threads);
  return line;
}

}  // namespace lmb::cli
