// The SIMD level of this process: which kernels (common/simd, infer/simd) run.
//
// Levels, per architecture, lowest first:
//   x86-64:  generic (the baseline ISA: SSE2), avx2 (AVX2 + POPCNT), avx512 (AVX-512 F, BW, DQ, VL;
//            the context-embedding column kernel also needs VPOPCNTDQ and falls back to the avx2
//            kernels without it);
//   aarch64: generic, neon (Advanced SIMD, part of every ARMv8-A CPU);
//   others:  generic.
// Every level computes the same results bit for bit (integer arithmetic, and IEEE additions in
// one fixed order: the build passes -ffp-contract=off, so that no multiply-add is fused in one
// kernel and not in another, nor on one architecture and not on another).
//
// The level is chosen once per process, at the first call of simd_level(): the best level the CPU
// supports, capped by the environment variable LMB_SIMD when it is set (generic, avx2, avx512,
// neon: a level of this architecture; a level above the CPU's gives the CPU's). `LMB_SIMD=generic
// ctest` runs the whole suite on the generic kernels. Kernel tables (embedding_kernels(),
// scoring_kernels(), ...) also exist for every other available level, for tests that compare each
// fast kernel with the generic one on the same inputs.
//
// Each kernel file is compiled with its own ISA flags (cmake: lmb_add_simd_sources) and guarded by
// the architecture; its code has internal linkage except for the kernel entry points, so that no
// inline or template function compiled with AVX2 or AVX-512 instructions can be merged into code
// that runs on a CPU without them (ctest common/simd_object_hygiene checks the object files).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace lmb {

enum class SimdLevel : int32_t {
  kGeneric = 0,
  kAvx2 = 1,
  kAvx512 = 2,
  kNeon = 3,
};

// "generic", "avx2", "avx512", "neon".
const char* simd_level_name(SimdLevel level);

// The levels compiled into this build for its architecture, lowest first (see the file comment).
std::vector<SimdLevel> compiled_simd_levels();

// Whether this CPU can run the kernels of `level` (compiled in and supported by the CPU).
bool simd_level_supported(SimdLevel level);

// The best level this CPU supports.
SimdLevel detected_simd_level();

// The level of `env` (the value of LMB_SIMD; null or empty = no cap) on a CPU whose best level is
// `detected`: the named level, or `detected` when that is lower. Throws lmb::Error for a name that
// is not a level of this architecture.
SimdLevel simd_level_from_env(const char* env, SimdLevel detected);

// The level of this process (detected once, capped by LMB_SIMD). Throws lmb::Error, at every
// call, when LMB_SIMD holds an unknown name.
SimdLevel simd_level();

// Whether this CPU has AVX-512 VPOPCNTDQ (the context-embedding column kernel of the avx512 level).
bool cpu_has_avx512_vpopcntdq();

}  // namespace lmb
