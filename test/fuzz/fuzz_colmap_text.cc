// Fuzz target: COLMAP text models (common/io/colmap_model.h). The input holds cameras.txt,
// images.txt and optionally points3D.txt, separated by lmb::fuzz::kFileSeparator; they are
// written to a scratch sparse folder and read with read_colmap_text.
#include <cstdint>
#include <filesystem>

#include "common/io/colmap_model.h"
#include "test/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto dir = lmb::fuzz::scratch_dir() / "sparse_text";
  std::filesystem::create_directories(dir);
  const auto parts = lmb::fuzz::split_files(data, size, 3);
  const char* names[] = {"cameras.txt", "images.txt", "points3D.txt"};
  for (size_t i = 0; i < 3; ++i) {
    if (i < parts.size()) {
      lmb::fuzz::write_file(dir / names[i], parts[i]);
    } else {
      std::filesystem::remove(dir / names[i]);
    }
  }
  lmb::fuzz::call_loader("read_colmap_text", [&] { lmb::read_colmap_text(dir); });
  return 0;
}
