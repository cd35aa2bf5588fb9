// An AVX2 kernel file that breaks the rule of common/simd/simd_level.h (for the ctest
// common/simd/object_hygiene_selftest): its inline helper has external linkage and is emitted
// out of line, as a weak symbol compiled with -mavx2.
namespace lmb::detail {

inline __attribute__((noinline)) int shared_helper(int x) { return 3 * x + 1; }

int bad_kernel_avx2(int x) { return shared_helper(x); }

}  // namespace lmb::detail
