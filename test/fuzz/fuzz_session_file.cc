// Fuzz target: a collection's sessions file sessions.txt (common/io/session_file.h), which
// `lboost map` reads. A file that is accepted must name at least one session, each with a valid,
// unique name, and round-trip: written and read back (no error), the same sessions in the same
// order.
#include <cstdint>
#include <cstdio>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "common/io/session_file.h"
#include "test/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = lmb::fuzz::scratch_dir() / "sessions.txt";
  lmb::fuzz::write_file(path, std::string_view(reinterpret_cast<const char*>(data), size));
  std::vector<lmb::MapSession> sessions;
  if (!lmb::fuzz::call_loader("read_session_file", [&] { sessions = lmb::read_session_file(path); })) return 0;
  if (sessions.empty()) __builtin_trap();
  std::set<std::string> names;
  for (const lmb::MapSession& s : sessions) {
    if (!names.insert(s.name).second) __builtin_trap();
  }
  try {
    for (const lmb::MapSession& s : sessions) lmb::check_session_name(s.name, "fuzz: a session read");
    const auto again_path = lmb::fuzz::scratch_dir() / "sessions_again.txt";
    lmb::write_session_file(sessions, again_path);
    const std::vector<lmb::MapSession> again = lmb::read_session_file(again_path);
    if (again.size() != sessions.size()) __builtin_trap();
    for (size_t i = 0; i < again.size(); ++i) {
      if (again[i].name != sessions[i].name || again[i].kind != sessions[i].kind) __builtin_trap();
    }
  } catch (const lmb::Error& e) {
    std::fprintf(stderr, "fuzz: the sessions read do not check or round-trip: %s\n", e.what());
    __builtin_trap();
  }
  return 0;
}
