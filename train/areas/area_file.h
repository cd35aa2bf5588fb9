// The areas file `lboost areas` writes (docs/areas.md): plain text a person can read, one summary
// line per area first, then each area's landmark ids.
//
//   lmb-areas 1
//   map_fingerprint 0123456789abcdef     (fingerprint_map of the map it splits, hex)
//   map_landmarks 99204
//   max_classes 7500
//   min_observations 5
//   overlap 1
//   reach 6.25                           (metres; the value the prior selection uses)
//   eligible 73574
//   areas 14
//   area 0 landmarks 7311 core 6890 truncated 0 cell -inf -inf -inf 2.9 inf inf bounds ...
//   ...
//   members 0 12 17 25 ...               (the landmark ids of area 0, ascending)
//   ...
// Lines starting with '#' are comments. Numbers are written with enough digits to read back
// exactly; cell ends may be -inf / inf.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "train/areas/area_split.h"

namespace lmb {

struct AreaFile {
  uint64_t map_fingerprint = 0;
  int64_t map_landmarks = 0;
  AreaSplit split;
};

// The text of the file (`source`: a comment line naming where it came from, may be empty).
std::string area_file_text(const AreaFile& file, const std::string& source);
// Writes it atomically. Throws lmb::Error naming the path.
void write_area_file(const std::filesystem::path& path, const AreaFile& file, const std::string& source);
// Reads and checks it. Throws lmb::Error "<path> line <n>: <what>" on any malformed, missing or
// inconsistent line (area ids out of order, more than max_classes landmarks, unsorted or
// out-of-range landmark ids, a members line that does not match its area's count, more areas than
// the file has lines for: checked before allocating). Without the map the header's values are only
// checked against each other; check_area_file_map checks them against the map.
AreaFile read_area_file(const std::filesystem::path& path);

// A 64-bit hash of a landmark id list (FNV-1a over the ids as little-endian int32): the same list
// gives the same value on every platform.
uint64_t landmark_list_hash(const std::vector<landmark_t>& landmarks);

// Checks an areas file read from `path` against the map it is used with: its map_fingerprint is
// fingerprint_map(map) and its map_landmarks the map's landmark count (so that every landmark id,
// below map_landmarks, is one of the map's). Throws lmb::Error naming the file, field and values.
void check_area_file_map(const AreaFile& file, const std::filesystem::path& path, const LandmarkMap& map);

// The landmarks of area `id` of the areas file at `path`, for training on `map`. Throws lmb::Error
// naming the file when it cannot be read, has no area `id`, or was made from another map
// (check_area_file_map).
std::vector<landmark_t> read_area_landmarks(const std::filesystem::path& path, int32_t id, const LandmarkMap& map);

// "FILE:ID" of `lboost train --area`: splits at the last ':'. Throws lmb::Error naming `what`.
void parse_area_reference(const std::string& text, const std::string& what, std::string* file, int32_t* id);

}  // namespace lmb
