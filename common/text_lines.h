// The one reader of the project's line-oriented text files (COLMAP text models, gravity files, TUM
// sequences, split lists): the data lines of a file with their line numbers, so that every error
// can name "<file> line <n>".
//
// A data line is any line that is not empty, not only white space and whose first non-blank
// character is not '#'. A trailing '\r' (CRLF files) is dropped. A UTF-8 byte order mark at the start
// of the file (some editors write one) is skipped. A NUL byte anywhere in the file is an error (a
// binary file, or a name that would cut the error messages short).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace lmb {

// The UTF-8 byte order mark; every text reader skips it at the start of a file.
inline constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";

// The number of bytes of a UTF-8 byte order mark at the start of `text` (3 or 0).
inline size_t utf8_bom_size(std::string_view text) { return text.substr(0, kUtf8Bom.size()) == kUtf8Bom ? 3 : 0; }

// `text` with its control bytes escaped (\0, \n, \t, \xNN), for quoting file content in an error
// message: a NUL or a line break would cut the message short or break it into lines.
std::string escape_control_bytes(std::string_view text);

class TextLineReader {
 public:
  // Reads the whole file (common/file_io.h read_file). Throws lmb::Error naming the path: missing,
  // a folder, unreadable, or a NUL byte ("<path> line N: contains a NUL byte").
  explicit TextLineReader(const std::filesystem::path& path);

  // Advances to the next data line; false at the end of the file.
  bool next();
  // The current data line (without its line break) and its 1-based number.
  const std::string& line() const { return line_; }
  int number() const { return number_; }
  // The current line split at white space (as `istream >> std::string` splits).
  std::vector<std::string> tokens() const;
  // "<path> line <number>", the prefix of every error about the current line.
  std::string where() const;
  // Advances to the next data line, which must be "<key> <values...>" with `count` values, and
  // returns the values. Throws lmb::Error naming the file (it ends first) or the line.
  std::vector<std::string> expect(const char* key, size_t count);
  const std::filesystem::path& path() const { return path_; }
  // The lines after the current one, comments and blank lines included: an upper bound on the data
  // lines left, to check a count a file declares before allocating for it.
  int64_t lines_left() const;

 private:
  std::filesystem::path path_;
  std::string text_;
  size_t pos_ = 0;
  int next_number_ = 0;
  int number_ = 0;
  std::string line_;
};

// Splits `line` at white space (space, tab, \v, \f, \r).
std::vector<std::string> split_fields(std::string_view line);

}  // namespace lmb
