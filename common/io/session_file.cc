#include "common/io/session_file.h"

#include <map>
#include <sstream>
#include <string_view>
#include <unordered_map>
#include <unordered_set>

#include "common/error.h"
#include "common/file_io.h"
#include "common/text_lines.h"

namespace lmb {

namespace fs = std::filesystem;

void check_session_name(const std::string& name, const std::string& where) {
  bool ok = !name.empty() && name != "." && name != "..";
  for (char c : name) {
    ok = ok && ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '_' ||
                c == '.');
  }
  LMB_CHECK(ok, where << ": session name '" << escape_control_bytes(name)
                      << "' (expected letters, digits, '-', '_' or '.': the image folder of the session)");
}

std::vector<MapSession> read_session_file(const fs::path& path) {
  const std::string text = read_file(path);
  std::vector<MapSession> sessions;
  std::unordered_map<std::string, int> listed_on;  // session name -> its line
  size_t pos = utf8_bom_size(text);
  int number = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + pos, end - pos);
    pos = end + 1;
    ++number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string at = path.string() + " line " + std::to_string(number);
    const std::vector<std::string> tokens = split_fields(line);
    LMB_CHECK(tokens.size() == 2, at << ": expected 2 fields (NAME KIND), got " << tokens.size());
    check_session_name(tokens[0], at);
    const auto [it, added] = listed_on.emplace(tokens[0], number);
    LMB_CHECK(added, at << ": duplicate session name " << tokens[0] << " (first on line " << it->second << ")");
    sessions.push_back(MapSession{tokens[0], parse_session_kind(escape_control_bytes(tokens[1]), at)});
  }
  LMB_CHECK(!sessions.empty(), path.string() << ": no session listed");
  return sessions;
}

void write_session_file(const std::vector<MapSession>& sessions, const fs::path& path) {
  std::unordered_set<std::string> names;
  for (const MapSession& s : sessions) {
    check_session_name(s.name, path.string());
    LMB_CHECK(names.insert(s.name).second, path.string() << ": duplicate session name " << s.name);
  }
  std::ostringstream out;
  out << "# Sessions of this collection: an image belongs to the session named by its first folder.\n"
      << "# KIND: map (builds the map, trains), query (held out, evaluated), outside (held out, not in the map).\n"
      << "# NAME KIND\n";
  for (const MapSession& s : sessions) out << s.name << ' ' << session_kind_name(s.kind) << '\n';
  write_file_atomically(path, out.str());
}

std::vector<int32_t> image_sessions(const std::vector<MapSession>& sessions, const ColmapModel& model,
                                    const fs::path& path) {
  std::map<std::string, int32_t> index;
  for (size_t s = 0; s < sessions.size(); ++s) index.emplace(sessions[s].name, static_cast<int32_t>(s));
  std::vector<int32_t> out;
  out.reserve(model.images.size());
  for (const ColmapImage& im : model.images) {
    const size_t slash = im.name.find('/');
    LMB_CHECK(slash != std::string::npos, path.string() << ": image " << im.name << " (image id " << im.image_id
                                                        << ") is in no session folder (names must be SESSION/...)");
    const auto it = index.find(im.name.substr(0, slash));
    LMB_CHECK(it != index.end(), path.string()
                                     << ": image " << im.name << " (image id " << im.image_id << "): its folder '"
                                     << im.name.substr(0, slash) << "' is not a session of this file");
    out.push_back(it->second);
  }
  return out;
}

}  // namespace lmb
