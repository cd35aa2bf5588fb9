// Fuzz target: per-image gravity files (common/io/gravity_file.h). Every direction read must be
// a finite unit vector.
#include <cmath>
#include <cstdint>
#include <string_view>

#include "common/io/gravity_file.h"
#include "test/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = lmb::fuzz::scratch_dir() / "gravity.txt";
  lmb::fuzz::write_file(path, std::string_view(reinterpret_cast<const char*>(data), size));
  lmb::fuzz::call_loader("read_gravity_file", [&] {
    for (const auto& [name, g] : lmb::read_gravity_file(path)) {
      if (!g.allFinite() || std::abs(g.norm() - 1.0) > 1e-9) __builtin_trap();
    }
  });
  return 0;
}
