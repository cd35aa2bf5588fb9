// The portable scoring kernels compiled for AVX2 (-mavx2 -mpopcnt; x86-64 only): 4 doubles or 16
// uint16 lanes a register.
#if defined(__x86_64__)
#include "infer/simd/scoring_body.h"
#include "infer/simd/scoring_kernels.h"

namespace lmb::detail {

LMB_DEFINE_SCORING_KERNELS(avx2)

}  // namespace lmb::detail
#endif
