// Fuzz target: map.h5 (common/io/map_h5.h). The input bytes are written to a scratch file and read
// with read_map_h5; a map that loads must pass validate_landmark_map.
#include <cstdint>
#include <string_view>

#include <H5Cpp.h>

#include "common/io/map_h5.h"
#include "test/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = [] {
    H5::Exception::dontPrint();
    return true;
  }();
  (void)quiet;
  const auto path = lmb::fuzz::scratch_dir() / "map.h5";
  lmb::fuzz::write_file(path, std::string_view(reinterpret_cast<const char*>(data), size));
  lmb::fuzz::call_loader("read_map_h5", [&] {
    const lmb::LandmarkMap map = lmb::read_map_h5(path);
    lmb::validate_landmark_map(map, "fuzz map");
  });
  return 0;
}
