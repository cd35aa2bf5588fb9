// COLMAP sparse models (cameras, images, points3D) in COLMAP's text format: the collection format
// that `lboost world` writes and `lboost map` reads. See
// https://colmap.github.io/format.html for the field definitions.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"

namespace lmb {

struct ColmapImage {
  int image_id = 0;
  int camera_id = 0;
  std::string name;  // relative to the collection's image folder, '/'-separated
  Rigid3d cam_from_world;
};

struct ColmapPoint3D {
  int64_t point3d_id = 0;
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  Eigen::Matrix<uint8_t, 3, 1> rgb = Eigen::Matrix<uint8_t, 3, 1>::Zero();
  double error = 0.0;
};

struct ColmapModel {
  std::map<int, Camera> cameras;     // by COLMAP camera id
  std::vector<ColmapImage> images;   // sorted by image id
  std::vector<ColmapPoint3D> points; // optional; the mapper does not need them
};

// Reads cameras.txt, images.txt and points3D.txt (the last may be absent) from `sparse_dir`.
// Throws lmb::Error naming the file, line and reason for malformed content: unknown camera models,
// wrong parameter counts, NaN values, non-unit quaternions, images referring to missing cameras,
// duplicate ids.
ColmapModel read_colmap_text(const std::filesystem::path& sparse_dir);

// Writes the three text files into `sparse_dir` (created if missing). Images carry no 2D points.
void write_colmap_text(const ColmapModel& model, const std::filesystem::path& sparse_dir);

// Checks that a quaternion read from a file is a rotation: finite and of unit norm within 1e-3
// (then normalized), else throws naming `where`.
Eigen::Quaterniond checked_rotation(double qw, double qx, double qy, double qz, const std::string& where);

}  // namespace lmb
