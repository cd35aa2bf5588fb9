// `lboost localize --image/--images`: photos (image files) localized with one model or a bundle of
// area models. Each photo is read as `lboost map` reads map images (OpenCV's decoder, grey), its
// keypoints and descriptors detected by the mapper's own detection (train/mapping/keypoint_detection.h,
// the inference library's OpenCV front-end), so a photo of a map frame gives that frame's keypoints
// and descriptors exactly; then localized with the camera and gravity the user gives.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "common/camera.h"
#include "common/detector_options.h"
#include "infer/area_bundle.h"
#include "infer/bundle_localizer.h"
#include "infer/localizer.h"
#include "infer/model.h"

namespace lmb::cli {

// The gravity of a photo when none is given: down along the image's y axis (x right, y down, z
// forward), a camera held upright and level.
inline const Eigen::Vector3d kUprightGravityInCam(0.0, 1.0, 0.0);

struct PhotoLocalizationOptions {
  Camera camera;  // every photo's (its size must be the photo's)
  // Gravity (down) in the camera frame, any non-zero length: per photo file name (the last path
  // component) when gravity_by_name is not empty, else gravity_in_cam for every photo.
  Eigen::Vector3d gravity_in_cam = kUprightGravityInCam;
  std::map<std::string, Eigen::Vector3d> gravity_by_name;
  std::string gravity_file;            // where gravity_by_name comes from (for messages)
  DetectorOptions detector;            // the mapper's settings; the detector must be the model's
  std::optional<PositionPrior> prior;  // bundle only: the areas it selects (every area without)
  int threads = 1;                     // photos localized at once (1..256)
};

// The image files of `dir` (not of its sub-folders) named *.png, *.jpg, *.jpeg, *.bmp, *.tif or
// *.tiff (any case), sorted by name. Throws lmb::Error "--images DIR: ..." when `dir` is not a
// folder or holds no such file.
std::vector<std::filesystem::path> list_photos(const std::filesystem::path& dir);

// Localizes the photos, in order, with `localizer`, or with `bundle_localizer` when it is not null
// (then `localizer` is ignored; options.prior applies). Returns {"camera", "gravity", "prior",
// "detector", "options", "calibration", "photos", "summary"} (docs/localize_photos.md lists the
// fields). A photo that cannot be read (missing, unreadable, not an image OpenCV decodes) gets an
// entry with its "error" and success false; the others go on. Throws lmb::Error, naming the photo,
// for a photo whose size is not the camera's or that is smaller than the detector takes, a photo
// without a line in the gravity file, a detector other than the model's, and threads outside
// 1..256 (the first such error in photo order).
nlohmann::json localize_photos(const std::vector<std::filesystem::path>& photos, const Localizer* localizer,
                               const BundleLocalizer* bundle_localizer, const PhotoLocalizationOptions& options);

// The summary as one line ("localize: N/M photos localized ...").
std::string photo_localization_summary_line(const nlohmann::json& summary, int threads);

}  // namespace lmb::cli
