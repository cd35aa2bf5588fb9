// COLMAP sparse models (cameras, images, points3D) in COLMAP's text format: the collection format
// that `lboost world` writes and `lboost map` reads. See
// https://colmap.github.io/format.html for the field definitions. The binary format is in
// common/io/colmap_binary.h; read_colmap_model() reads either.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"

namespace lmb {

// One keypoint of an image as COLMAP stores it: pixel position (COLMAP's convention, the centre of
// the top-left pixel is (0.5, 0.5)) and the 3D point it observes, or kNoPoint3D.
struct ColmapPoint2D {
  static constexpr int64_t kNoPoint3D = -1;  // COLMAP's kInvalidPoint3DId (uint64 max) read as int64
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  int64_t point3d_id = kNoPoint3D;
  bool operator==(const ColmapPoint2D&) const = default;
};

struct ColmapImage {
  int image_id = 0;
  int camera_id = 0;
  std::string name;  // relative to the collection's image folder, '/'-separated
  Rigid3d cam_from_world;
  std::vector<ColmapPoint2D> points2d;  // optional (empty for rendered worlds); the mapper ignores them
};

// One observation of a 3D point: (image id, index into that image's points2d).
struct ColmapTrackElement {
  int image_id = 0;
  int point2d_idx = 0;
  bool operator==(const ColmapTrackElement&) const = default;
};

struct ColmapPoint3D {
  int64_t point3d_id = 0;
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  Eigen::Matrix<uint8_t, 3, 1> rgb = Eigen::Matrix<uint8_t, 3, 1>::Zero();
  double error = 0.0;
  std::vector<ColmapTrackElement> track;  // optional
};

struct ColmapModel {
  std::map<int, Camera> cameras;      // by COLMAP camera id
  std::vector<ColmapImage> images;    // sorted by image id
  std::vector<ColmapPoint3D> points;  // optional; the mapper does not need them
};

// Reads cameras.txt, images.txt and points3D.txt (the last may be absent) from `sparse_dir`.
// Throws lmb::Error naming the file, line and reason for malformed content: unknown camera models,
// wrong parameter counts, NaN values, non-unit quaternions, images referring to missing cameras,
// duplicate ids. POINTS2D lines and points3D tracks are read when present.
ColmapModel read_colmap_text(const std::filesystem::path& sparse_dir);

// Writes the three text files into `sparse_dir` (created if missing), with 2D points and tracks
// when the model has them.
void write_colmap_text(const ColmapModel& model, const std::filesystem::path& sparse_dir);

enum class ColmapFormat { kText, kBinary };

// Reads a sparse model in either format, as COLMAP's own reader does: the binary files
// (cameras.bin, images.bin; points3D.bin optional) when cameras.bin or images.bin exists, else
// the text files. A folder holding both formats is read as binary (COLMAP's choice, and what
// `colmap mapper` writes); `format`, when given, receives the format read. Throws lmb::Error
// naming the folder when it holds neither, or only part of the binary model.
ColmapModel read_colmap_model(const std::filesystem::path& sparse_dir, ColmapFormat* format = nullptr);

// Checks, before any long job starts, that every image of `model` is a readable image file under
// `image_dir`: it exists (symbolic links are followed; a dangling link counts as missing), is a
// regular file, opens, and starts with the signature of an image format OpenCV decodes (JPEG,
// PNG, TIFF, BMP, PNM, WebP, JPEG 2000, OpenEXR, Radiance HDR, Sun raster). Throws lmb::Error for
// the first failure in image-id order, naming the image id, the path and the reason. It does not
// decode pixels: a corrupt body is only found by the decoder.
void check_collection_images(const ColmapModel& model, const std::filesystem::path& image_dir);

// Why a 3D point's track element does not fit `model` (images sorted by id): "" when it refers to
// an image of the model and, when that image has 2D points, to one of them; else the reason.
// Both readers check every track element with it.
std::string colmap_track_error(const ColmapModel& model, const ColmapTrackElement& element);

// Why an image name read from a sparse model could not be used as a path inside the image folder:
// "" when it can (relative, '/'-separated, no empty, "." or ".." component), else the reason, e.g.
// "image name '../x.png' leaves the image folder ('..' component)". Both readers check every name,
// so no caller joins a name that escapes the folder (`import colmap` writes links at these names).
std::string image_name_error(const std::string& name);
// Throws lmb::Error "<where>: <reason>" when image_name_error(name) is not empty.
void check_image_name(const std::string& name, const std::string& where);

// Checks that a quaternion read from a file is a rotation: finite and of unit norm within 1e-3
// (then normalized), else throws naming `where`.
Eigen::Quaterniond checked_rotation(double qw, double qx, double qy, double qz, const std::string& where);

}  // namespace lmb
