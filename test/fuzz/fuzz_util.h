// Shared pieces of the libFuzzer targets (test/fuzz, built with -DLMB_FUZZ=ON by scripts/fuzz.sh).
//
// Every target feeds one input to one loader of outside data. The loader's contract is "returns a
// valid object or throws lmb::Error": any other exception escaping it (std::bad_alloc,
// std::out_of_range, a library's own exception type) is reported as a crash by
// call_loader(), and memory errors, undefined behaviour, leaks, timeouts and allocations beyond
// -rss_limit_mb / -malloc_limit_mb are reported by the sanitizers and libFuzzer themselves.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

#include "common/error.h"
#include "common/file_container.h"

namespace lmb::fuzz {

// Separates the files of a multi-file input (a COLMAP model's cameras, images, points3D):
// "cameras.txt bytes" kFileSeparator "images.txt bytes" [kFileSeparator "points3D.txt bytes"].
// test/fuzz/lmb.dict lists it so that mutations keep or make the split.
inline constexpr std::string_view kFileSeparator = "\n#LMB-FUZZ-NEXT-FILE#\n";

// Splits the input at kFileSeparator into at most `max_parts` parts (the last takes the rest).
inline std::vector<std::string> split_files(const uint8_t* data, size_t size, size_t max_parts) {
  const std::string_view all(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> parts;
  size_t begin = 0;
  while (parts.size() + 1 < max_parts) {
    const size_t at = all.find(kFileSeparator, begin);
    if (at == std::string_view::npos) break;
    parts.emplace_back(all.substr(begin, at - begin));
    begin = at + kFileSeparator.size();
  }
  parts.emplace_back(all.substr(begin));
  return parts;
}

// The inverse of split_files (used by the seed generator).
inline std::string join_files(const std::vector<std::string>& parts) {
  std::string out;
  for (size_t i = 0; i < parts.size(); ++i) {
    if (i > 0) out += kFileSeparator;
    out += parts[i];
  }
  return out;
}

// A per-process scratch folder for loaders that read from paths (map.h5, COLMAP, gravity).
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    std::filesystem::path d = std::filesystem::path(tmp ? tmp : "/tmp") / ("lmb_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

inline void write_file(const std::filesystem::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out.good()) {
    std::fprintf(stderr, "fuzz: cannot write %s\n", path.c_str());
    std::abort();
  }
}

// A copy of a container image (common/file_container.h) whose payload length and CRC fields are
// recomputed, so that mutations of the payload reach the payload parser instead of stopping at
// the CRC check. Inputs shorter than the header are returned unchanged.
inline std::vector<uint8_t> with_repaired_header(const uint8_t* data, size_t size) {
  std::vector<uint8_t> out(data, data + size);
  if (size < kContainerHeaderBytes) return out;
  const uint64_t length = size - kContainerHeaderBytes;
  const uint32_t crc = crc32(out.data() + kContainerHeaderBytes, length);
  for (int i = 0; i < 8; ++i) out[12 + i] = static_cast<uint8_t>(length >> (8 * i));
  for (int i = 0; i < 4; ++i) out[20 + i] = static_cast<uint8_t>(crc >> (8 * i));
  return out;
}

// Runs a loader call: returns true when it succeeded, false when it threw lmb::Error (the
// expected answer to bad input); anything else thrown aborts, which libFuzzer reports as a crash.
template <class F>
bool call_loader(const char* loader, F&& f) {
  try {
    f();
    return true;
  } catch (const lmb::Error&) {
    return false;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz: %s threw a non-lmb::Error exception: %s\n", loader, e.what());
    std::abort();
  } catch (...) {
    std::fprintf(stderr, "fuzz: %s threw a non-std exception\n", loader);
    std::abort();
  }
}

}  // namespace lmb::fuzz
