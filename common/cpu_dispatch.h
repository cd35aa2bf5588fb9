// Run-time choice between an AVX2 build of a hot function and the baseline x86-64 one (x86-64
// only: elsewhere the macro is empty). The inference kernels do not use it: they live in the SIMD
// layer (common/simd/simd_level.h), whose level LMB_SIMD caps. What still does: the learner's
// screening and scoring loops, and FrameContext::compute_dims / compute_dims_columns, whose clone
// differs only in the popcount instruction of the dominance counts (integer work, the same
// values); LMB_SIMD does not cap these clones.
//
// LMB_CLONES_AVX2 before a function definition makes GCC compile it twice (target_clones): for
// AVX2 (which also enables POPCNT, BMI and SSE4.2) and for the default ISA; the dynamic loader
// picks one once, by the CPU it runs on. Both clones must compute the same results: only use it
// on code whose arithmetic is exact or IEEE-identical in both ISAs (integer work, double
// additions without contraction into FMA, which the "avx2" target does not enable).
//
// Under ThreadSanitizer the clone resolver (an IFUNC the dynamic loader runs before the TSan
// runtime starts) is instrumented and crashes every program at load: TSan builds
// (scripts/tsan.sh) take the baseline code only.
#pragma once

#if !defined(__x86_64__)
#define LMB_CLONES_AVX2
#elif defined(__SANITIZE_THREAD__)
#define LMB_CLONES_AVX2
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define LMB_CLONES_AVX2
#endif
#endif
#ifndef LMB_CLONES_AVX2
#define LMB_CLONES_AVX2 __attribute__((target_clones("avx2", "default")))
#endif
// clang 14 (the fuzz build) emits a target_clones member function defined in one file without the
// plain symbol that callers in other files link to: clang builds take the baseline code only.
#if defined(__clang__)
#undef LMB_CLONES_AVX2
#define LMB_CLONES_AVX2
#endif
