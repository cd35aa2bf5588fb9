// Bit count of a 64-bit word for the kernel bodies (internal linkage: see simd_level.h).
#pragma once

#include <cstdint>

namespace lmb::detail {
namespace {

// The popcnt instruction when the including file is compiled with it, CNT on aarch64; else a
// branch-free sum instead of libgcc's call.
[[gnu::always_inline]] inline int32_t popcount64(uint64_t x) {
#if defined(__POPCNT__) || defined(__aarch64__)
  return __builtin_popcountll(x);
#else
  x = x - ((x >> 1) & 0x5555555555555555ull);
  x = (x & 0x3333333333333333ull) + ((x >> 2) & 0x3333333333333333ull);
  x = (x + (x >> 4)) & 0x0F0F0F0F0F0F0F0Full;
  return static_cast<int32_t>((x * 0x0101010101010101ull) >> 56);
#endif
}

}  // namespace
}  // namespace lmb::detail
