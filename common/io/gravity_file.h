// Per-image gravity for real collections: a text file `gravity.txt` beside the collection's
// `sparse/` folder. One line per image, '#' starts a comment:
//   IMAGE_NAME GX GY GZ
// (GX, GY, GZ) is the direction of gravity (pointing DOWN, towards the ground) in that image's
// CAMERA frame (COLMAP's: x right, y down, z forward), in any scale; it is normalized on read.
// IMAGE_NAME is the image's name exactly as in the sparse model (no spaces). Rendered worlds need
// no gravity file: their gravity is -up of the world axis given to `lboost map --up`.
#pragma once

#include <filesystem>
#include <map>
#include <string>

#include <Eigen/Core>

#include "common/io/colmap_model.h"

namespace lmb {

// Reads a gravity file; returns unit gravity directions by image name. Throws lmb::Error naming
// the file, line and reason: wrong field count, a value that is not a finite number, a zero vector
// (norm below 1e-9), a duplicate name.
std::map<std::string, Eigen::Vector3d> read_gravity_file(const std::filesystem::path& path);

// As above, and checks the names against `model`: every name must be an image of the model
// (else "image name X is not in the sparse model") and every image of the model must have a line
// (else "no gravity for image X", naming the first such image in id order).
std::map<std::string, Eigen::Vector3d> read_gravity_file(const std::filesystem::path& path, const ColmapModel& model);

// Writes a gravity file (directions as given, 17 significant digits), replacing `path`.
void write_gravity_file(const std::map<std::string, Eigen::Vector3d>& gravity_in_cam,
                        const std::filesystem::path& path);

}  // namespace lmb
