#include "common/text_lines.h"

#include <cstdio>
#include <cstring>

#include "common/error.h"
#include "common/file_io.h"

namespace lmb {

namespace {
// White space as std::isspace in the C locale (what `istream >> string` splits at).
bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r'; }
}  // namespace

TextLineReader::TextLineReader(const std::filesystem::path& path) : path_(path), text_(read_file(path)) {
  const size_t nul = text_.find('\0');
  if (nul != std::string::npos) {
    int line = 1;
    for (size_t i = 0; i < nul; ++i) line += text_[i] == '\n';
    LMB_FAIL(path_.string() << " line " << line << ": contains a NUL byte (not a text file?)");
  }
  pos_ = utf8_bom_size(text_);
}

bool TextLineReader::next() {
  while (pos_ < text_.size()) {
    size_t end = text_.find('\n', pos_);
    if (end == std::string::npos) end = text_.size();
    line_.assign(text_, pos_, end - pos_);
    pos_ = end + 1;
    ++next_number_;
    if (!line_.empty() && line_.back() == '\r') line_.pop_back();
    const size_t first = line_.find_first_not_of(" \t");
    if (first == std::string::npos || line_[first] == '#') continue;
    number_ = next_number_;
    return true;
  }
  line_.clear();
  return false;
}

std::vector<std::string> TextLineReader::tokens() const { return split_fields(line_); }

int64_t TextLineReader::lines_left() const {
  if (pos_ >= text_.size()) return 0;
  int64_t lines = 0;
  for (size_t i = pos_; i < text_.size(); ++i) lines += text_[i] == '\n';
  return lines + (text_.back() != '\n');
}

std::string TextLineReader::where() const { return path_.string() + " line " + std::to_string(number_); }

std::vector<std::string> TextLineReader::expect(const char* key, size_t count) {
  LMB_CHECK(next(), path_.string() << ": ends before the '" << key << "' line");
  std::vector<std::string> t = tokens();
  LMB_CHECK(!t.empty() && t[0] == key && t.size() == count + 1,
            where() << ": expected '" << key << "' and " << count << " value(s), found '" << line_ << "'");
  t.erase(t.begin());
  return t;
}

std::string escape_control_bytes(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '\0') {
      out += "\\0";
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c < 0x20 || c == 0x7F) {
      char hex[8];
      std::snprintf(hex, sizeof(hex), "\\x%02X", c);
      out += hex;
    } else {
      out += ch;
    }
  }
  return out;
}

std::vector<std::string> split_fields(std::string_view line) {
  std::vector<std::string> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_blank(line[i])) ++i;
    size_t j = i;
    while (j < line.size() && !is_blank(line[j])) ++j;
    if (j > i) out.emplace_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

}  // namespace lmb
