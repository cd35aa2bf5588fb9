// map.h5: the landmark map on disk (versioned HDF5, serial library). The schema is documented in
// docs/map_h5.md; in short, root attributes `format` = "landmarkboost-map", `format_version` = 2,
// `detector`, `descriptor_bytes`, and groups /cameras, /sessions, /frames, /keypoints, /landmarks
// holding the columns of lmb::LandmarkMap. Version 1 files (no sessions) are still read: their
// frames get the sessions "map" and "query" (assign_sessions_from_query_flags).
#pragma once

#include <filesystem>
#include <string>

#include "common/landmark_map.h"

namespace lmb {

inline constexpr const char* kMapH5Format = "landmarkboost-map";
inline constexpr int kMapH5Version = 2;  // the version written; 1 is read too

// Checks that a map is self-consistent: sessions with unique names and known kinds (at least one
// when there are frames), frames referencing existing sessions (is_query set exactly outside map
// sessions; no landmark observed in an outside session) and cameras with
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
