// Hamming distances of one query descriptor to many rows (common/hamming.h).
#include "common/hamming.h"

namespace lmb {

namespace {

// Hamming distances of one query to n rows; the loop body is inlined into a popcnt-enabled and a
// generic wrapper, chosen once at run time.
template <int kWords>
inline __attribute__((always_inline)) void hamming_rows_body(const uint8_t* q, const uint8_t* rows, int64_t n,
                                                             int bytes, uint16_t* out) {
  if constexpr (kWords > 0) {
    uint64_t qw[kWords];
    std::memcpy(qw, q, sizeof(qw));
    for (int64_t i = 0; i < n; ++i) {
      const uint8_t* r = rows + i * bytes;
      int d = 0;
      for (int w = 0; w < kWords; ++w) {
        uint64_t x;
        std::memcpy(&x, r + 8 * w, 8);
        d += __builtin_popcountll(x ^ qw[w]);
      }
      out[i] = static_cast<uint16_t>(d);
    }
  } else {
    for (int64_t i = 0; i < n; ++i) out[i] = static_cast<uint16_t>(hamming_distance(q, rows + i * bytes, bytes));
  }
}

template <int kWords>
__attribute__((target("popcnt"))) void hamming_rows_popcnt(const uint8_t* q, const uint8_t* rows, int64_t n,
                                                           int bytes, uint16_t* out) {
  hamming_rows_body<kWords>(q, rows, n, bytes, out);
}

template <int kWords>
void hamming_rows_generic(const uint8_t* q, const uint8_t* rows, int64_t n, int bytes, uint16_t* out) {
  hamming_rows_body<kWords>(q, rows, n, bytes, out);
}

}  // namespace

void hamming_rows(const uint8_t* q, const uint8_t* rows, int64_t n, int bytes, uint16_t* out) {
  static const bool has_popcnt = __builtin_cpu_supports("popcnt");
  if (has_popcnt) {
    switch (bytes) {
      case 32: return hamming_rows_popcnt<4>(q, rows, n, bytes, out);
      case 64: return hamming_rows_popcnt<8>(q, rows, n, bytes, out);
      default: return hamming_rows_popcnt<0>(q, rows, n, bytes, out);
    }
  }
  switch (bytes) {
    case 32: return hamming_rows_generic<4>(q, rows, n, bytes, out);
    case 64: return hamming_rows_generic<8>(q, rows, n, bytes, out);
    default: return hamming_rows_generic<0>(q, rows, n, bytes, out);
  }
}

}  // namespace lmb
