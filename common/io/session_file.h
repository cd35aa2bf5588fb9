// The sessions of a collection: a text file `sessions.txt` beside the collection's `sparse/`
// folder. One line per session, '#' starts a comment:
//   NAME KIND
// NAME is the first folder of the image names of the session's frames (the image `map-2/000012.png`
// belongs to the session `map-2`): letters, digits, '-', '_' and '.'. KIND is `map` (builds the map
// and trains the classifier), `query` (held out and evaluated) or `outside` (held out, recorded
// where the map has no landmarks). The file's order is the sessions' order in map.h5.
// A collection without the file has the sessions of `lboost map --query-prefix` (see
// train/mapping/mapper.h): "map" and "query".
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/io/colmap_model.h"
#include "common/landmark_map.h"

namespace lmb {

inline constexpr const char* kSessionFileName = "sessions.txt";

// Checks a session name for a sessions file (non-empty; letters, digits, '-', '_', '.'; not "."
// or ".."). Throws lmb::Error "<where>: ..." otherwise.
void check_session_name(const std::string& name, const std::string& where);

// Reads a sessions file (lines as common/text_lines.h reads them: CRLF and a leading UTF-8 byte order
// mark are fine). Throws lmb::Error naming the file, line and reason: wrong field count, a bad name
// or kind (quoted with control bytes such as NUL escaped), a duplicate name (with the line of its
// first listing), no session at all.
std::vector<MapSession> read_session_file(const std::filesystem::path& path);

// Writes a sessions file, replacing `path`. Throws lmb::Error for a bad or duplicate name or a
// failed write.
void write_session_file(const std::vector<MapSession>& sessions, const std::filesystem::path& path);

// The session of each image of `model` (model order): the index of the session named by the
// image name's first folder. Throws lmb::Error naming `path` (the sessions file) and the first
// image, in id order, without a folder or whose folder is no session.
std::vector<int32_t> image_sessions(const std::vector<MapSession>& sessions, const ColmapModel& model,
                                    const std::filesystem::path& path);

}  // namespace lmb
