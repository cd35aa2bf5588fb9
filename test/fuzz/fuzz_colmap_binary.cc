// Fuzz target: COLMAP binary models (common/io/colmap_binary.h). The input holds cameras.bin,
// images.bin and optionally points3D.bin, separated by lmb::fuzz::kFileSeparator; they are written
// to a scratch sparse folder and read with read_colmap_binary.
#include <cstdint>
#include <filesystem>

#include "common/io/colmap_binary.h"
#include "test/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto dir = lmb::fuzz::scratch_dir() / "sparse_bin";
  std::filesystem::create_directories(dir);
  const auto parts = lmb::fuzz::split_files(data, size, 3);
  const char* names[] = {"cameras.bin", "images.bin", "points3D.bin"};
  for (size_t i = 0; i < 3; ++i) {
    if (i < parts.size()) {
      lmb::fuzz::write_file(dir / names[i], parts[i]);
    } else {
      std::filesystem::remove(dir / names[i]);
    }
  }
  lmb::fuzz::call_loader("read_colmap_binary", [&] { lmb::read_colmap_binary(dir); });
  return 0;
}
