// Fuzz target: the areas file of `lboost areas` (train/areas/area_file.h read_area_file), which
// `lboost train --area` and `lboost bundle` read. A file that is accepted must hold areas with ids
// equal to their positions and ascending landmark ids below map_landmarks, at most max_classes each,
// and round-trip: the text written from it reads back (no error) to the same text.
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

#include "test/fuzz/fuzz_util.h"
#include "train/areas/area_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = lmb::fuzz::scratch_dir() / "areas.txt";
  lmb::fuzz::write_file(path, std::string_view(reinterpret_cast<const char*>(data), size));
  lmb::AreaFile file;
  if (!lmb::fuzz::call_loader("read_area_file", [&] { file = lmb::read_area_file(path); })) return 0;
  for (size_t i = 0; i < file.split.areas.size(); ++i) {
    const lmb::Area& a = file.split.areas[i];
    if (a.id != static_cast<int32_t>(i)) __builtin_trap();
    if (static_cast<int64_t>(a.landmarks.size()) > file.split.options.max_classes) __builtin_trap();
    for (size_t k = 0; k < a.landmarks.size(); ++k) {
      if (a.landmarks[k] < 0 || a.landmarks[k] >= file.map_landmarks) __builtin_trap();
      if (k > 0 && a.landmarks[k] <= a.landmarks[k - 1]) __builtin_trap();
    }
  }
  const std::string written = lmb::area_file_text(file, "");
  const auto again_path = lmb::fuzz::scratch_dir() / "areas_again.txt";
  lmb::fuzz::write_file(again_path, written);
  try {
    if (lmb::area_file_text(lmb::read_area_file(again_path), "") != written) __builtin_trap();
  } catch (const lmb::Error& e) {
    std::fprintf(stderr, "fuzz: the written areas file does not read back: %s\n", e.what());
    __builtin_trap();
  }
  return 0;
}
