#include "train/import/split_rule.h"

#include <unistd.h>

#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

std::vector<SplitFrame> frames(int n) {
  std::vector<SplitFrame> f(n);
  for (int i = 0; i < n; ++i) {
    std::ostringstream key, file;
    key << 'f' << i;
    file << "dir/f" << i << ".jpg";
    f[i].keys = {key.str(), file.str()};
    f[i].time_s = 1000.0 + 0.5 * i;
  }
  return f;
}

std::vector<int> map_indices(const std::vector<bool>& is_map) {
  std::vector<int> out;
  for (size_t i = 0; i < is_map.size(); ++i) {
    if (is_map[i]) out.push_back(static_cast<int>(i));
  }
  return out;
}

std::string error_of(const std::string& rule) {
  try {
    parse_split_rule(rule);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(SplitRule, EveryFirstAndTime) {
  EXPECT_EQ(map_indices(assign_map_frames(parse_split_rule("every:3"), frames(8), true)), (std::vector<int>{0, 3, 6}));
  EXPECT_EQ(map_indices(assign_map_frames(parse_split_rule("every:1"), frames(3), true)), (std::vector<int>{0, 1, 2}));
  // first:0.6 of 8 = 4.8 -> 5 frames.
  EXPECT_EQ(map_indices(assign_map_frames(parse_split_rule("first:0.6"), frames(8), true)),
            (std::vector<int>{0, 1, 2, 3, 4}));
  // Times 0, 0.5, 1.0, ... from the first frame; [1, 2.5) holds frames 2..4.
  EXPECT_EQ(map_indices(assign_map_frames(parse_split_rule("time:1:2.5"), frames(8), true)),
            (std::vector<int>{2, 3, 4}));
}

TEST(SplitRule, ListMatchesAnyKeyAndRejectsUnknownEntries) {
  const fs::path list = fs::temp_directory_path() / ("lmb_split_" + std::to_string(::getpid()) + ".txt");
  std::ofstream(list) << "# map frames\nf1\n\ndir/f5.jpg extra fields ignored\n";
  EXPECT_EQ(map_indices(assign_map_frames(parse_split_rule("list:" + list.string()), frames(8), false)),
            (std::vector<int>{1, 5}));
  std::ofstream(list, std::ios::trunc) << "f1\nf99\n";
  try {
    assign_map_frames(parse_split_rule("list:" + list.string()), frames(8), false);
    ADD_FAILURE() << "unknown list entry accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("entry 'f99' names no frame"), std::string::npos) << e.what();
  }
  std::ofstream(list, std::ios::trunc) << "f1\nf1\n";
  EXPECT_NE(error_of("list:" + list.string()).find("line 2: duplicate entry f1"), std::string::npos);
  fs::remove(list);
  EXPECT_NE(error_of("list:" + list.string()).find(list.string() + ": cannot open file: No such file or directory"),
            std::string::npos);
}

// map-list:FILE names the map frames (the same as list:FILE); query-list:FILE names the queries.
TEST(SplitRule, MapListAndQueryList) {
  const fs::path list = fs::temp_directory_path() / ("lmb_split_q_" + std::to_string(::getpid()) + ".txt");
  std::ofstream(list) << "# frames\nf1\ndir/f5.jpg\n";
  EXPECT_EQ(map_indices(assign_map_frames(parse_split_rule("map-list:" + list.string()), frames(8), false)),
            (std::vector<int>{1, 5}));
  EXPECT_EQ(map_indices(assign_map_frames(parse_split_rule("query-list:" + list.string()), frames(8), false)),
            (std::vector<int>{0, 2, 3, 4, 6, 7}));
  // Every frame a query: no map frame is left.
  std::ofstream(list, std::ios::trunc) << "f0\nf1\n";
  try {
    assign_map_frames(parse_split_rule("query-list:" + list.string()), frames(2), false);
    ADD_FAILURE() << "a split without map frames accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("leaves no map frame"), std::string::npos) << e.what();
  }
  fs::remove(list);
  EXPECT_NE(
      error_of("query-list:" + list.string()).find(list.string() + ": cannot open file: No such file or directory"),
      std::string::npos);
}

TEST(SplitRule, BadRulesFailClearly) {
  EXPECT_NE(error_of("every").find("expected every:N, first:F, time:A:B, map-list:FILE or query-list:FILE"),
            std::string::npos);
  EXPECT_NE(error_of("every:0").find("N must be an integer >= 1"), std::string::npos);
  EXPECT_NE(error_of("every:2.5").find("N must be an integer >= 1"), std::string::npos);
  EXPECT_NE(error_of("first:0").find("F must be in (0, 1]"), std::string::npos);
  EXPECT_NE(error_of("first:x").find("F is not a number: 'x'"), std::string::npos);
  EXPECT_NE(error_of("time:3:1").find("A must be smaller than B"), std::string::npos);
  EXPECT_NE(error_of("random:3").find("unknown rule 'random'"), std::string::npos);
  EXPECT_THROW(assign_map_frames(parse_split_rule("time:0:1"), frames(3), false), Error);
  // A rule that selects nothing.
  EXPECT_THROW(assign_map_frames(parse_split_rule("time:100:200"), frames(3), true), Error);
}

}  // namespace
}  // namespace lmb
