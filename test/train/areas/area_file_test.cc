#include "train/areas/area_file.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/feature_space.h"
#include "common/file_io.h"
#include "test/train/areas/area_test_map.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir() {
  const fs::path dir = fs::temp_directory_path() / ("lmb_area_file_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

AreaFile corridor_areas() {
  AreaSplitOptions options;
  options.max_classes = 100;
  options.overlap = 0.5;
  AreaFile file;
  const LandmarkMap map = test::corridor_map();
  file.split = split_map_into_areas(map, options);
  file.map_fingerprint = 0x0123456789ABCDEFull;
  file.map_landmarks = static_cast<int64_t>(map.landmarks.size());
  return file;
}

TEST(AreaFile, RoundTripsExactly) {
  const AreaFile file = corridor_areas();
  const fs::path path = temp_dir() / "areas.txt";
  write_area_file(path, file, "test corridor");
  const AreaFile back = read_area_file(path);
  EXPECT_EQ(back.map_fingerprint, file.map_fingerprint);
  EXPECT_EQ(back.map_landmarks, file.map_landmarks);
  EXPECT_EQ(back.split.options.max_classes, 100);
  EXPECT_EQ(back.split.options.overlap, 0.5);
  EXPECT_EQ(back.split.options.reach, file.split.options.reach);
  EXPECT_GT(back.split.options.reach, 0.0);
  EXPECT_EQ(back.split.num_eligible, file.split.num_eligible);
  ASSERT_EQ(back.split.areas.size(), file.split.areas.size());
  for (size_t i = 0; i < file.split.areas.size(); ++i) {
    const Area& a = file.split.areas[i];
    const Area& b = back.split.areas[i];
    EXPECT_EQ(b.id, a.id);
    EXPECT_EQ(b.landmarks, a.landmarks);
    EXPECT_EQ(b.cell.lo, a.cell.lo);  // bit-exact, infinities included
    EXPECT_EQ(b.cell.hi, a.cell.hi);
    EXPECT_EQ(b.bounds.lo, a.bounds.lo);
    EXPECT_EQ(b.bounds.hi, a.bounds.hi);
    EXPECT_EQ(b.num_core, a.num_core);
    EXPECT_EQ(b.num_truncated, a.num_truncated);
  }
  // The same text again: the writer is a function of the split.
  EXPECT_EQ(area_file_text(back, "test corridor"), read_file(path));
  fs::remove_all(path.parent_path());
}

// Replaces the first occurrence of `from` in the file's text by `to`; expects the reader to fail
// with a message containing `needle` and, with names_its_line, naming the line replaced.
void expect_rejected(const std::string& from, const std::string& to, const std::string& needle,
                     bool names_its_line = false) {
  std::string text = area_file_text(corridor_areas(), "");
  const size_t start = from.rfind("lmb-areas", 0) == 0 ? 0 : text.find("map_fingerprint");  // past the comments
  const size_t at = text.find(from, start);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  const fs::path path = temp_dir() / "bad_areas.txt";
  write_file_atomically(path, text);
  try {
    read_area_file(path);
    ADD_FAILURE() << "accepted: " << from << " -> " << to;
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path.string()), std::string::npos) << what;
    EXPECT_NE(what.find(needle), std::string::npos) << "expected '" << needle << "' in: " << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    if (names_its_line) {
      const size_t first = at + (from[0] == '\n' ? 1 : 0);  // where the line replaced starts
      const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(first), '\n');
      EXPECT_NE(what.find(" line " + std::to_string(line) + ": "), std::string::npos) << line << ": " << what;
    }
  }
  fs::remove_all(path.parent_path());
}

TEST(AreaFile, RejectsMalformedFilesNamingTheLine) {
  expect_rejected("lmb-areas 1", "lmb-areas 2", "format version 2");
  expect_rejected("map_fingerprint 0123456789abcdef", "map_fingerprint 0123xyz", "16 hex digits");
  expect_rejected("max_classes 100", "max_classes 0", "max_classes 0 is outside", true);
  expect_rejected("overlap 0.5", "overlap nan", "overlap is not", true);
  expect_rejected("map_landmarks ", "map_landmarks x", "map_landmarks is not an integer", true);
  expect_rejected("\nareas ", "\nareas x", "areas is not an integer", true);
  expect_rejected("area 1 ", "area 2 ", "line 12: area id 2 is outside [1, 1]");
  expect_rejected(" bounds ", " bound ", "expected 'bounds'");
  expect_rejected("members 0 ", "members 0 1 ", "landmarks");                // one more id than its count
  expect_rejected(" core ", " core 7 ", "expected 'area' and 21 value(s)");  // wrong field count
  // Out-of-order and out-of-range landmark ids.
  const AreaFile file = corridor_areas();
  const std::string first = std::to_string(file.split.areas[0].landmarks[0]);
  const std::string second = std::to_string(file.split.areas[0].landmarks[1]);
  expect_rejected("members 0 " + first + " " + second, "members 0 " + second + " " + first, "ascending");
  expect_rejected("members 0 " + first, "members 0 400", "landmark id 400 is outside [0, 399]");
}

TEST(AreaFile, RejectsTruncatedAndMissingFiles) {
  const std::string full = area_file_text(corridor_areas(), "");
  const fs::path path = temp_dir() / "short_areas.txt";
  auto error = [&](const std::string& text) -> std::string {
    write_file_atomically(path, text);
    try {
      read_area_file(path);
    } catch (const Error& e) {
      return e.what();
    }
    return "(accepted)";
  };
  // The last line cut: fewer lines than the areas need, found at the header.
  const std::string cut = full.substr(0, full.rfind("members"));
  EXPECT_NE(error(cut).find("but the file has only"), std::string::npos) << error(cut);
  // The last members line a comment: as many lines, one members line short.
  const std::string commented = cut + "# members\n";
  EXPECT_NE(error(commented).find("ends before the members of area"), std::string::npos) << error(commented);
  EXPECT_THROW(read_area_file(path.parent_path() / "missing.txt"), Error);
  fs::remove_all(path.parent_path());
}

// A count in the header is checked against the lines the file has before anything is allocated
// for it.
TEST(AreaFile, AreaCountBeyondTheFileIsRefusedBeforeAllocating) {
  const AreaFile file = corridor_areas();
  const size_t areas = file.split.areas.size();
  ASSERT_GE(areas, 2u);
  expect_rejected("\nareas " + std::to_string(areas) + "\n", "\nareas 1000000\n",
                  "areas 1000000, but the file has only " + std::to_string(2 * areas) +
                      " line(s) left (each area needs an area and a members line)",
                  true);
  expect_rejected("\nareas " + std::to_string(areas) + "\n", "\nareas " + std::to_string(areas + 1) + "\n",
                  "areas " + std::to_string(areas + 1) + ", but the file has only", true);
  expect_rejected("\nareas " + std::to_string(areas) + "\n", "\nareas 1000001\n", "areas 1000001 is outside", true);
}

// Against the map it is used with (train --area, bundle --map): a header the map contradicts is
// refused, even when the file itself is consistent.
TEST(AreaFile, HeaderValuesAreCheckedAgainstTheMap) {
  const LandmarkMap map = test::corridor_map();
  AreaFile file = corridor_areas();
  file.map_fingerprint = fingerprint_map(map);
  const fs::path path = temp_dir() / "map_areas.txt";
  write_area_file(path, file, "");
  EXPECT_NO_THROW(check_area_file_map(read_area_file(path), path, map));
  EXPECT_EQ(read_area_landmarks(path, 0, map), file.split.areas[0].landmarks);

  file.map_landmarks = 2147483647;  // read alone, still a valid file
  write_area_file(path, file, "");
  ASSERT_NO_THROW(read_area_file(path));
  const std::string expected = path.string() + ": map_landmarks 2147483647, but its map has " +
                               std::to_string(map.landmarks.size()) +
                               " landmarks (an edited or damaged file); run lboost areas on this map";
  for (int via = 0; via < 2; ++via) {
    try {
      if (via == 0) check_area_file_map(read_area_file(path), path, map);
      if (via == 1) read_area_landmarks(path, 0, map);
      ADD_FAILURE() << "accepted map_landmarks 2147483647";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()), expected);
    }
  }
  file.map_landmarks = static_cast<int64_t>(map.landmarks.size());
  file.map_fingerprint ^= 1;
  write_area_file(path, file, "");
  try {
    check_area_file_map(read_area_file(path), path, map);
    ADD_FAILURE() << "accepted another map's fingerprint";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(": made from another map"), std::string::npos) << e.what();
  }
  fs::remove_all(path.parent_path());
}

TEST(AreaFile, ParsesAreaReferences) {
  std::string file;
  int32_t id = -1;
  parse_area_reference("runs/a:b/areas.txt:12", "--area", &file, &id);
  EXPECT_EQ(file, "runs/a:b/areas.txt");
  EXPECT_EQ(id, 12);
  EXPECT_THROW(parse_area_reference("areas.txt", "--area", &file, &id), Error);
  EXPECT_THROW(parse_area_reference("areas.txt:", "--area", &file, &id), Error);
  EXPECT_THROW(parse_area_reference("areas.txt:-1", "--area", &file, &id), Error);
  EXPECT_THROW(parse_area_reference("areas.txt:1x", "--area", &file, &id), Error);
}

}  // namespace
}  // namespace lmb
