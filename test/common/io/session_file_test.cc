#include "common/io/session_file.h"

#include <unistd.h>

#include <fstream>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;
using namespace std::string_literals;

class SessionFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_session_file_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string error_of(const std::string& text) {
    const fs::path path = dir_ / "sessions.txt";
    std::ofstream(path) << text;
    try {
      read_session_file(path);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }

  fs::path dir_;
};

TEST_F(SessionFileTest, RoundTripKeepsOrderAndKinds) {
  const std::vector<MapSession> sessions = {{"map", SessionKind::kMap},
                                            {"run_2.b", SessionKind::kMap},
                                            {"query", SessionKind::kQuery},
                                            {"elsewhere", SessionKind::kOutside}};
  write_session_file(sessions, dir_ / "sessions.txt");
  const std::vector<MapSession> read = read_session_file(dir_ / "sessions.txt");
  ASSERT_EQ(read.size(), sessions.size());
  for (size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].name, sessions[i].name);
    EXPECT_EQ(read[i].kind, sessions[i].kind);
  }
  // Comments, blank lines and CRLF are fine.
  EXPECT_EQ(error_of("# a comment\n\nmap map\r\n  query   query\n"), "");
}

TEST_F(SessionFileTest, BadLinesNameFileLineAndReason) {
  const std::string at = (dir_ / "sessions.txt").string() + " line 2: ";
  EXPECT_EQ(error_of("map map\nquery\n"), at + "expected 2 fields (NAME KIND), got 1");
  EXPECT_EQ(error_of("map map\nquery later\n"), at + "session kind 'later' (expected map, query or outside)");
  EXPECT_EQ(error_of("map map\nmap query\n"), at + "duplicate session name map (first on line 1)");
  EXPECT_NE(error_of("map map\nq/x query\n").find(at + "session name 'q/x'"), std::string::npos);
  EXPECT_NE(error_of("map map\n.. query\n").find(at + "session name '..'"), std::string::npos);
  EXPECT_EQ(error_of("# nothing\n"), (dir_ / "sessions.txt").string() + ": no session listed");
  EXPECT_NE(error_of("").find("no session listed"), std::string::npos);
  EXPECT_THROW(read_session_file(dir_ / "missing.txt"), Error);
  EXPECT_THROW(write_session_file({{"a b", SessionKind::kMap}}, dir_ / "w.txt"), Error);
  EXPECT_THROW(write_session_file({{"a", SessionKind::kMap}, {"a", SessionKind::kQuery}}, dir_ / "w.txt"), Error);
}

TEST_F(SessionFileTest, ManySessionsParseAndADuplicateNamesBothLines) {
  const int n = 100000;
  std::string text = "# NAME KIND\n";
  for (int i = 0; i < n; ++i) {
    text += 's';
    text += std::to_string(i);
    text += i % 3 == 0 ? " map\n" : " query\n";
  }
  const fs::path path = dir_ / "sessions.txt";
  std::ofstream(path) << text;
  const std::vector<MapSession> read = read_session_file(path);
  ASSERT_EQ(read.size(), static_cast<size_t>(n));
  EXPECT_EQ(read[0].name, "s0");
  EXPECT_EQ(read[n - 1].name, std::string("s") + std::to_string(n - 1));
  EXPECT_EQ(read[n - 1].kind, (n - 1) % 3 == 0 ? SessionKind::kMap : SessionKind::kQuery);
  // The duplicate of the session on line 6 (s4), listed last.
  EXPECT_EQ(error_of(text + "s4 outside\n"),
            path.string() + " line " + std::to_string(n + 2) + ": duplicate session name s4 (first on line 6)");
}

TEST_F(SessionFileTest, ANulByteIsQuotedEscapedInTheMessage) {
  const std::string at = (dir_ / "sessions.txt").string() + " line 2: ";
  const std::string error = error_of("map map\nqu\0ery-tail query\n"s);
  EXPECT_EQ(error, at + "session name 'qu\\0ery-tail' (expected letters, digits, '-', '_' or '.': the image folder "
                        "of the session)");
  EXPECT_EQ(error.find('\0'), std::string::npos);
  EXPECT_EQ(error_of("map ma\0p\n"s), (dir_ / "sessions.txt").string() +
                                          " line 1: session kind 'ma\\0p' (expected map, query or "
                                          "outside)");
}

TEST_F(SessionFileTest, ALeadingByteOrderMarkIsSkippedLikeInEveryTextReader) {
  const fs::path path = dir_ / "sessions.txt";
  std::ofstream(path) << "\xEF\xBB\xBF# NAME KIND\r\nmap map\r\nquery query\r\n";
  std::vector<MapSession> read = read_session_file(path);
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[0].name, "map");
  std::ofstream(path) << "\xEF\xBB\xBFmap map\n";
  read = read_session_file(path);
  ASSERT_EQ(read.size(), 1u);
  EXPECT_EQ(read[0].name, "map");
  // Only at the start of the file: elsewhere it is part of a name, which is refused.
  EXPECT_NE(error_of("map map\n\xEF\xBB\xBFquery query\n").find("line 2: session name '\xEF\xBB\xBFquery'"),
            std::string::npos);
}

TEST_F(SessionFileTest, ImagesBelongToTheSessionOfTheirFirstFolder) {
  const std::vector<MapSession> sessions = {{"map", SessionKind::kMap}, {"query", SessionKind::kQuery}};
  ColmapModel model;
  for (const char* name : {"map/1.png", "query/2.png", "map/sub/3.png"}) {
    ColmapImage im;
    im.image_id = static_cast<int>(model.images.size()) + 1;
    im.name = name;
    model.images.push_back(im);
  }
  EXPECT_EQ(image_sessions(sessions, model, dir_ / "sessions.txt"), (std::vector<int32_t>{0, 1, 0}));
  model.images[1].name = "mapping/2.png";
  try {
    image_sessions(sessions, model, dir_ / "sessions.txt");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("image mapping/2.png (image id 2): its folder 'mapping' is not a session"),
              std::string::npos)
        << e.what();
  }
  model.images[1].name = "2.png";
  EXPECT_THROW(image_sessions(sessions, model, dir_ / "sessions.txt"), Error);
}

}  // namespace
}  // namespace lmb
