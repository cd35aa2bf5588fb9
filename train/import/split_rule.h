// The map/query split of a collection. Map frames build the landmark map and train the
// classifier; query frames (named "query/...", `lboost map --query-prefix`) are held out and
// localized. Rules, in the sequence order of the frames:
//   every:N        frames 0, N, 2N, ... are map frames, the others query (N >= 1; N = 1: all map)
//   first:F        the first round(F * count) frames are map frames, the rest query (0 < F <= 1)
//   time:A:B       frames whose time since the first frame lies in [A, B) seconds are map frames
//                  (needs timestamps, e.g. a TUM sequence)
//   map-list:FILE  FILE lists the map frames, one per line (first field; '#' comments), the
//                  other frames are queries; every entry must name a frame
//   query-list:FILE  the same, FILE listing the query frames (the other frames are map frames)
//   list:FILE      the older spelling of map-list:FILE
#pragma once

#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace lmb {

struct SplitRule {
  enum class Kind { kEvery, kFirst, kTime, kList };
  Kind kind = Kind::kEvery;
  int every = 3;
  double first_fraction = 0.6;
  double time_begin_s = 0.0;
  double time_end_s = 0.0;
  std::filesystem::path list_file;
  std::vector<std::string> list;    // entries of list_file, in file order
  bool list_names_queries = false;  // query-list: the entries are the query frames
};

// Parses "every:N", "first:F", "time:A:B", "map-list:FILE", "query-list:FILE" or "list:FILE"
// (reading FILE). Throws lmb::Error naming the rule (or the list file and line) and the reason.
SplitRule parse_split_rule(const std::string& text);

// A frame as the split sees it: the names a list entry may use for it (e.g. a TUM timestamp and
// its file name) and its time in seconds (only for time rules).
struct SplitFrame {
  std::vector<std::string> keys;
  double time_s = 0.0;
};

// Returns, for each frame in sequence order, true for a map frame. Throws lmb::Error when a list
// entry names no frame, when a time rule meets frames without time, or when the rule leaves no
// map frame.
std::vector<bool> assign_map_frames(const SplitRule& rule, const std::vector<SplitFrame>& frames,
                                    bool frames_have_time);

}  // namespace lmb
