#include "common/simd/simd_level.h"

#include <cstdlib>
#include <cstring>
#include <iterator>

#include "common/error.h"

namespace lmb {

namespace {

// The levels of this architecture, lowest first.
#if defined(__x86_64__)
constexpr SimdLevel kLevels[] = {SimdLevel::kGeneric, SimdLevel::kAvx2, SimdLevel::kAvx512};
#elif defined(__aarch64__)
constexpr SimdLevel kLevels[] = {SimdLevel::kGeneric, SimdLevel::kNeon};
#else
constexpr SimdLevel kLevels[] = {SimdLevel::kGeneric};
#endif

#if defined(__x86_64__)
bool cpu_has(const char* what) {
  __builtin_cpu_init();
  // __builtin_cpu_supports takes a string literal only: one branch per feature.
  if (std::strcmp(what, "avx2") == 0) return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
  if (std::strcmp(what, "avx512") == 0) {
    return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
           __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl");
  }
  if (std::strcmp(what, "avx512vpopcntdq") == 0) return __builtin_cpu_supports("avx512vpopcntdq");
  return false;
}
#endif

}  // namespace

const char* simd_level_name(SimdLevel level) {
  switch (level) {
    case SimdLevel::kGeneric: return "generic";
    case SimdLevel::kAvx2: return "avx2";
    case SimdLevel::kAvx512: return "avx512";
    case SimdLevel::kNeon: return "neon";
  }
  return "unknown";
}

std::vector<SimdLevel> compiled_simd_levels() { return std::vector<SimdLevel>(std::begin(kLevels), std::end(kLevels)); }

bool simd_level_supported(SimdLevel level) {
  switch (level) {
    case SimdLevel::kGeneric: return true;
#if defined(__x86_64__)
    case SimdLevel::kAvx2: return cpu_has("avx2");
    case SimdLevel::kAvx512: return cpu_has("avx2") && cpu_has("avx512");
#elif defined(__aarch64__)
    case SimdLevel::kNeon: return true;
#endif
    default: return false;
  }
}

bool cpu_has_avx512_vpopcntdq() {
#if defined(__x86_64__)
  return simd_level_supported(SimdLevel::kAvx512) && cpu_has("avx512vpopcntdq");
#else
  return false;
#endif
}

SimdLevel detected_simd_level() {
  SimdLevel best = SimdLevel::kGeneric;
  for (SimdLevel l : kLevels) {
    if (simd_level_supported(l)) best = l;
  }
  return best;
}

SimdLevel simd_level_from_env(const char* env, SimdLevel detected) {
  if (env == nullptr || env[0] == '\0') return detected;
  std::string names;
  for (SimdLevel l : kLevels) {
    if (std::strcmp(env, simd_level_name(l)) == 0) {
      // Levels of one architecture are listed lowest first: the lower of the two.
      for (SimdLevel d : kLevels) {
        if (d == l || d == detected) return d;
      }
    }
    names += std::string(names.empty() ? "" : ", ") + simd_level_name(l);
  }
  LMB_FAIL("LMB_SIMD=" << env << ": not a SIMD level of this build (" << names << ")");
}

SimdLevel simd_level() {
  static const SimdLevel level = simd_level_from_env(std::getenv("LMB_SIMD"), detected_simd_level());
  return level;
}

}  // namespace lmb
