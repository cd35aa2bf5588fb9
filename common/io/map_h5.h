// map.h5: the landmark map on disk (versioned HDF5, serial library). The schema is documented in
// docs/map_h5.md; in short, root attributes `format` = "landmarkboost-map", `format_version` = 1,
// `detector`, `descriptor_bytes`, and groups /cameras, /frames, /keypoints, /landmarks holding the
// columns of lmb::LandmarkMap.
#pragma once

#include <filesystem>
#include <string>

#include "common/landmark_map.h"

namespace lmb {

inline constexpr const char* kMapH5Format = "landmarkboost-map";
inline constexpr int kMapH5Version = 1;

// Checks that a map is self-consistent: cameras valid, frames referencing existing cameras with
// contiguous keypoint ranges ("frame after frame") covering all keypoints, unit quaternions and
// gravity, finite values, descriptor and landmark arrays of matching length, keypoint landmarks in
// range and landmark observation counts equal to the counts found in keypoint_landmark.
// Throws lmb::Error prefixed by `where` and naming the field.
void validate_landmark_map(const LandmarkMap& map, const std::string& where);

// Validates `map`, then writes it to a temporary file beside `path`, fsyncs it and renames it over
// `path`, so a crash or an error never leaves a partial file under `path`. Throws lmb::Error naming
// the file and reason.
void write_map_h5(const LandmarkMap& map, const std::filesystem::path& path);

// Reads and validates a map. Every failure (missing file, not HDF5, truncated or damaged, another
// format or version, missing datasets, inconsistent shapes, indices out of range, non-finite
// values) throws lmb::Error "<path>: <field>: <reason>".
LandmarkMap read_map_h5(const std::filesystem::path& path);

}  // namespace lmb
