// The SIMD level: names, the levels of this architecture, detection and the LMB_SIMD cap.
#include "common/simd/simd_level.h"

#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

TEST(SimdLevel, LevelsOfThisArchitectureLowestFirst) {
  const std::vector<SimdLevel> levels = compiled_simd_levels();
  ASSERT_FALSE(levels.empty());
  EXPECT_EQ(levels.front(), SimdLevel::kGeneric);
#if defined(__x86_64__)
  EXPECT_EQ(levels, (std::vector<SimdLevel>{SimdLevel::kGeneric, SimdLevel::kAvx2, SimdLevel::kAvx512}));
#elif defined(__aarch64__)
  EXPECT_EQ(levels, (std::vector<SimdLevel>{SimdLevel::kGeneric, SimdLevel::kNeon}));
  EXPECT_TRUE(simd_level_supported(SimdLevel::kNeon));  // Advanced SIMD is part of ARMv8-A
#endif
  EXPECT_TRUE(simd_level_supported(SimdLevel::kGeneric));
  EXPECT_TRUE(simd_level_supported(detected_simd_level()));
  // A supported level's lower levels are supported too.
  bool above = false;
  for (SimdLevel l : levels) {
    if (!simd_level_supported(l)) above = true;
    EXPECT_TRUE(!above || !simd_level_supported(l)) << simd_level_name(l);
  }
  EXPECT_STREQ(simd_level_name(SimdLevel::kAvx512), "avx512");
  EXPECT_STREQ(simd_level_name(SimdLevel::kNeon), "neon");
}

TEST(SimdLevel, EnvironmentCapsTheDetectedLevel) {
  const std::vector<SimdLevel> levels = compiled_simd_levels();
  const SimdLevel top = levels.back();
  EXPECT_EQ(simd_level_from_env(nullptr, top), top);
  EXPECT_EQ(simd_level_from_env("", top), top);
  for (SimdLevel wanted : levels) {
    // On the best CPU of the architecture: the named level; on a generic CPU: generic.
    EXPECT_EQ(simd_level_from_env(simd_level_name(wanted), top), wanted);
    EXPECT_EQ(simd_level_from_env(simd_level_name(wanted), SimdLevel::kGeneric), SimdLevel::kGeneric);
  }
  try {
    simd_level_from_env("sse9", top);
    FAIL() << "an unknown level must be an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("LMB_SIMD=sse9"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("generic"), std::string::npos) << e.what();
  }
#if defined(__x86_64__)
  EXPECT_THROW(simd_level_from_env("neon", top), Error);  // not a level of this architecture
#elif defined(__aarch64__)
  EXPECT_THROW(simd_level_from_env("avx2", top), Error);
#endif
}

TEST(SimdLevel, ProcessLevelFollowsLmbSimd) {
  // The process level is the detected one capped by LMB_SIMD, as ctest sets it (or not).
  const char* env = std::getenv("LMB_SIMD");
  EXPECT_EQ(simd_level(), simd_level_from_env(env, detected_simd_level()));
  std::printf("SIMD level: %s (detected %s, LMB_SIMD=%s)\n", simd_level_name(simd_level()),
              simd_level_name(detected_simd_level()), env ? env : "");
}

}  // namespace
}  // namespace lmb
