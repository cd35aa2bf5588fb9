#include "common/landmark_map.h"

#include "common/error.h"

namespace lmb {

const char* session_kind_name(SessionKind kind) {
  switch (kind) {
    case SessionKind::kMap: return "map";
    case SessionKind::kQuery: return "query";
    case SessionKind::kOutside: return "outside";
  }
  return "unknown";
}

SessionKind parse_session_kind(const std::string& text, const std::string& where) {
  if (text == "map") return SessionKind::kMap;
  if (text == "query") return SessionKind::kQuery;
  if (text == "outside") return SessionKind::kOutside;
  LMB_FAIL(where << ": session kind '" << text << "' (expected map, query or outside)");
}

std::vector<frame_t> LandmarkMap::map_session_frames() const {
  std::vector<frame_t> out;
  for (frame_t f = 0; f < num_frames(); ++f) {
    const int32_t s = frames[f].session;
    const bool map_session =
        s >= 0 && static_cast<size_t>(s) < sessions.size() && sessions[s].kind == SessionKind::kMap;
    if (map_session && !frames[f].is_query) out.push_back(f);
  }
  return out;
}

int32_t LandmarkMap::find_session(const std::string& name) const {
  for (size_t s = 0; s < sessions.size(); ++s) {
    if (sessions[s].name == name) return static_cast<int32_t>(s);
  }
  return -1;
}

void assign_sessions_from_query_flags(LandmarkMap* map) {
  LMB_CHECK(map->sessions.empty(),
            "assign_sessions_from_query_flags: the map already has " << map->sessions.size() << " sessions");
  map->sessions.push_back(MapSession{"map", SessionKind::kMap});
  bool any_query = false;
  for (const MapFrame& f : map->frames) any_query = any_query || f.is_query;
  if (any_query) map->sessions.push_back(MapSession{"query", SessionKind::kQuery});
  for (MapFrame& f : map->frames) f.session = f.is_query ? 1 : 0;
}

}  // namespace lmb
