#include "train/areas/area_file.h"

#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <vector>

#include "common/error.h"
#include "common/feature_space.h"
#include "common/file_io.h"
#include "common/text_lines.h"
#include "common/text_parse.h"

namespace lmb {

namespace {

// A number that may be -inf / inf (cell ends), never NaN.
int64_t parse_integer(const std::string& token, const std::string& where, const std::string& field, int64_t lo,
                      int64_t hi) {
  const char* begin = token.c_str();
  char* end = nullptr;
  errno = 0;
  const long long v = token.empty() ? 0 : std::strtoll(begin, &end, 10);
  LMB_CHECK(!token.empty() && end == begin + token.size() && errno != ERANGE,
            where << ": " << field << " is not an integer: '" << token << "'");
  LMB_CHECK(v >= lo && v <= hi, where << ": " << field << " " << v << " is outside [" << lo << ", " << hi << "]");
  return v;
}

}  // namespace

std::string area_file_text(const AreaFile& file, const std::string& source) {
  const AreaSplit& s = file.split;
  std::ostringstream os;
  os << "lmb-areas 1\n";
  if (!source.empty()) os << "# " << source << "\n";
  os << "# area ID landmarks N core N truncated N cell LO_X LO_Y LO_Z HI_X HI_Y HI_Z "
        "bounds LO_X LO_Y LO_Z HI_X HI_Y HI_Z; then per area: members ID LANDMARK_ID...\n";
  char hex[24];
  std::snprintf(hex, sizeof(hex), "%016" PRIx64, file.map_fingerprint);
  os << "map_fingerprint " << hex << "\n";
  os << "map_landmarks " << file.map_landmarks << "\n";
  os << "max_classes " << s.options.max_classes << "\n";
  os << "min_observations " << s.options.min_observations << "\n";
  os << "overlap " << exact_number_text(s.options.overlap) << "\n";
  os << "reach " << exact_number_text(s.options.reach) << "\n";
  os << "eligible " << s.num_eligible << "\n";
  os << "areas " << s.areas.size() << "\n";
  for (const Area& a : s.areas) {
    os << "area " << a.id << " landmarks " << a.landmarks.size() << " core " << a.num_core << " truncated "
       << a.num_truncated << " cell";
    for (int i = 0; i < 3; ++i) os << " " << exact_number_text(a.cell.lo[i]);
    for (int i = 0; i < 3; ++i) os << " " << exact_number_text(a.cell.hi[i]);
    os << " bounds";
    for (int i = 0; i < 3; ++i) os << " " << exact_number_text(a.bounds.lo[i]);
    for (int i = 0; i < 3; ++i) os << " " << exact_number_text(a.bounds.hi[i]);
    os << "\n";
  }
  for (const Area& a : s.areas) {
    os << "members " << a.id;
    for (landmark_t l : a.landmarks) os << " " << l;
    os << "\n";
  }
  return os.str();
}

void write_area_file(const std::filesystem::path& path, const AreaFile& file, const std::string& source) {
  write_file_atomically(path, area_file_text(file, source));
}

AreaFile read_area_file(const std::filesystem::path& path) {
  TextLineReader in(path);
  AreaFile file;
  AreaSplit& s = file.split;
  const auto expect = [&in](const char* key, size_t count) { return in.expect(key, count); };
  {
    const auto t = expect("lmb-areas", 1);
    LMB_CHECK(t[0] == "1", in.where() << ": format version " << t[0] << " is not supported (this build reads 1)");
  }
  {
    const auto t = expect("map_fingerprint", 1);
    char* end = nullptr;
    errno = 0;
    file.map_fingerprint = std::strtoull(t[0].c_str(), &end, 16);
    LMB_CHECK(t[0].size() == 16 && end == t[0].c_str() + t[0].size() && errno != ERANGE,
              in.where() << ": map_fingerprint is not 16 hex digits: '" << t[0] << "'");
  }
  // A "<key> <value>" line's value; `where` then names that line (read before it is used: the
  // order in which a call's arguments are evaluated is unspecified).
  std::string where;
  auto value = [&](const char* key) {
    std::string v = expect(key, 1)[0];
    where = in.where();
    return v;
  };
  std::string v = value("map_landmarks");
  file.map_landmarks = parse_integer(v, where, "map_landmarks", 1, INT32_MAX);
  v = value("max_classes");
  s.options.max_classes = static_cast<int32_t>(parse_integer(v, where, "max_classes", 1, INT32_MAX));
  v = value("min_observations");
  s.options.min_observations = static_cast<int32_t>(parse_integer(v, where, "min_observations", 1, INT32_MAX));
  v = value("overlap");
  s.options.overlap = parse_finite_number(v, where, "overlap");
  LMB_CHECK(s.options.overlap >= 0.0, where << ": overlap " << s.options.overlap << " is negative");
  v = value("reach");
  s.options.reach = parse_finite_number(v, where, "reach");
  LMB_CHECK(s.options.reach >= 0.0, where << ": reach " << s.options.reach << " is negative");
  v = value("eligible");
  s.num_eligible = parse_integer(v, where, "eligible", 1, file.map_landmarks);
  v = value("areas");
  const int64_t num_areas = parse_integer(v, where, "areas", 1, 1000000);
  // Before allocating for them: each area takes two lines (its area line and its members line).
  LMB_CHECK(num_areas <= in.lines_left() / 2, where << ": areas " << num_areas << ", but the file has only "
                                                    << in.lines_left()
                                                    << " line(s) left (each area needs an area and a members line)");
  s.areas.resize(static_cast<size_t>(num_areas));
  std::vector<int64_t> counts(s.areas.size());
  for (int64_t i = 0; i < num_areas; ++i) {
    const auto t = expect("area", 21);
    const std::string w = in.where();
    Area& a = s.areas[static_cast<size_t>(i)];
    a.id = static_cast<int32_t>(parse_integer(t[0], w, "area id", i, i));
    const char* names[5] = {"landmarks", "core", "truncated", "cell", "bounds"};
    const int at[5] = {1, 3, 5, 7, 14};
    for (int k = 0; k < 5; ++k) {
      LMB_CHECK(t[at[k]] == names[k], w << ": expected '" << names[k] << "', found '" << t[at[k]] << "'");
    }
    counts[static_cast<size_t>(i)] = parse_integer(t[2], w, "landmarks", 1, s.options.max_classes);
    a.num_core = parse_integer(t[4], w, "core", 0, INT64_MAX);
    a.num_truncated = parse_integer(t[6], w, "truncated", 0, INT64_MAX);
    for (int k = 0; k < 3; ++k) a.cell.lo[k] = parse_number_or_infinity(t[8 + k], w, "cell");
    for (int k = 0; k < 3; ++k) a.cell.hi[k] = parse_number_or_infinity(t[11 + k], w, "cell");
    for (int k = 0; k < 3; ++k) a.bounds.lo[k] = parse_finite_number(t[15 + k], w, "bounds");
    for (int k = 0; k < 3; ++k) a.bounds.hi[k] = parse_finite_number(t[18 + k], w, "bounds");
    for (int k = 0; k < 3; ++k) {
      LMB_CHECK(a.cell.lo[k] <= a.cell.hi[k], w << ": cell lower end above its upper end on axis " << k);
    }
  }
  for (int64_t i = 0; i < num_areas; ++i) {
    LMB_CHECK(in.next(), path.string() << ": ends before the members of area " << i);
    const std::vector<std::string> t = in.tokens();
    const std::string w = in.where();
    LMB_CHECK(t.size() >= 2 && t[0] == "members", w << ": expected 'members " << i << " ...'");
    parse_integer(t[1], w, "members area id", i, i);
    Area& a = s.areas[static_cast<size_t>(i)];
    LMB_CHECK(static_cast<int64_t>(t.size()) - 2 == counts[static_cast<size_t>(i)],
              w << ": area " << i << " lists " << t.size() - 2 << " landmarks, its area line says "
                << counts[static_cast<size_t>(i)]);
    a.landmarks.reserve(t.size() - 2);
    for (size_t k = 2; k < t.size(); ++k) {
      const auto l = static_cast<landmark_t>(parse_integer(t[k], w, "landmark id", 0, file.map_landmarks - 1));
      LMB_CHECK(a.landmarks.empty() || l > a.landmarks.back(),
                w << ": landmark ids must be ascending and distinct (" << l << " after " << a.landmarks.back() << ")");
      a.landmarks.push_back(l);
    }
  }
  LMB_CHECK(!in.next(), in.where() << ": unexpected line after the last area's members");
  return file;
}

uint64_t landmark_list_hash(const std::vector<landmark_t>& landmarks) {
  uint64_t h = 0xcbf29ce484222325ull;
  for (landmark_t l : landmarks) {
    const auto v = static_cast<uint32_t>(l);
    for (int b = 0; b < 4; ++b) h = (h ^ ((v >> (8 * b)) & 0xFFu)) * 0x100000001b3ull;
  }
  return h;
}

void check_area_file_map(const AreaFile& file, const std::filesystem::path& path, const LandmarkMap& map) {
  const uint64_t fingerprint = fingerprint_map(map);
  char want[24], got[24];
  std::snprintf(want, sizeof(want), "%016" PRIx64, fingerprint);
  std::snprintf(got, sizeof(got), "%016" PRIx64, file.map_fingerprint);
  LMB_CHECK(file.map_fingerprint == fingerprint, path.string() << ": made from another map (map_fingerprint " << got
                                                               << ", this map's is " << want
                                                               << "); run lboost areas on this map");
  const auto landmarks = static_cast<int64_t>(map.landmarks.size());
  LMB_CHECK(file.map_landmarks == landmarks, path.string() << ": map_landmarks " << file.map_landmarks
                                                           << ", but its map has " << landmarks
                                                           << " landmarks (an edited or damaged file); run lboost "
                                                              "areas on this map");
}

std::vector<landmark_t> read_area_landmarks(const std::filesystem::path& path, int32_t id, const LandmarkMap& map) {
  AreaFile file = read_area_file(path);
  LMB_CHECK(id >= 0 && static_cast<size_t>(id) < file.split.areas.size(),
            path.string() << ": has no area " << id << " (it has " << file.split.areas.size() << ", ids 0.."
                          << file.split.areas.size() - 1 << ")");
  check_area_file_map(file, path, map);
  return std::move(file.split.areas[static_cast<size_t>(id)].landmarks);
}

void parse_area_reference(const std::string& text, const std::string& what, std::string* file, int32_t* id) {
  const size_t colon = text.rfind(':');
  LMB_CHECK(colon != std::string::npos && colon > 0 && colon + 1 < text.size(),
            what << " '" << text << "': expected FILE:ID (an areas file of lboost areas and an area id)");
  *file = text.substr(0, colon);
  *id = static_cast<int32_t>(parse_integer(text.substr(colon + 1), what + " '" + text + "'", "area id", 0, INT32_MAX));
}

}  // namespace lmb
