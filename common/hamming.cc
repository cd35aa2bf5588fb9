// Hamming distances of one query descriptor to many rows (common/hamming.h).
#include "common/hamming.h"

namespace lmb {

namespace {

// The distance of one row to a query held as kWords 64-bit words; inlined into both wrappers of
// each kernel below, so its popcount follows the wrapper's target.
template <int kWords>
inline __attribute__((always_inline)) int words_distance(const uint64_t* qw, const uint8_t* r) {
  int d = 0;
  for (int w = 0; w < kWords; ++w) {
    uint64_t x;
    std::memcpy(&x, r + 8 * w, 8);
    d += __builtin_popcountll(x ^ qw[w]);
  }
  return d;
}

// Hamming distances of one query to n rows; the loop body is inlined into a popcnt-enabled and a
// generic wrapper, chosen once at run time.
template <int kWords>
inline __attribute__((always_inline)) void hamming_rows_body(const uint8_t* q, const uint8_t* rows, int64_t n,
                                                             int bytes, uint16_t* out) {
  if constexpr (kWords > 0) {
    uint64_t qw[kWords];
    std::memcpy(qw, q, sizeof(qw));
    for (int64_t i = 0; i < n; ++i) {
      const int d = words_distance<kWords>(qw, rows + i * bytes);
      out[i] = static_cast<uint16_t>(d);
    }
  } else {
    for (int64_t i = 0; i < n; ++i) out[i] = static_cast<uint16_t>(hamming_distance(q, rows + i * bytes, bytes));
  }
}

template <int kWords>
__attribute__((target("popcnt"))) void hamming_rows_popcnt(const uint8_t* q, const uint8_t* rows, int64_t n, int bytes,
                                                           uint16_t* out) {
  hamming_rows_body<kWords>(q, rows, n, bytes, out);
}

template <int kWords>
void hamming_rows_generic(const uint8_t* q, const uint8_t* rows, int64_t n, int bytes, uint16_t* out) {
  hamming_rows_body<kWords>(q, rows, n, bytes, out);
}

// The smallest distance of q to n rows, with the same two wrappers.
template <int kWords>
inline __attribute__((always_inline)) int hamming_min_body(const uint8_t* q, const uint8_t* rows, int64_t n,
                                                           int bytes) {
  int best = 8 * bytes + 1;
  if constexpr (kWords > 0) {
    uint64_t qw[kWords];
    std::memcpy(qw, q, sizeof(qw));
    for (int64_t i = 0; i < n; ++i) {
      const int d = words_distance<kWords>(qw, rows + i * bytes);
      best = d < best ? d : best;
    }
  } else {
    for (int64_t i = 0; i < n; ++i) {
      const int d = hamming_distance(q, rows + i * bytes, bytes);
      best = d < best ? d : best;
    }
  }
  return best;
}

template <int kWords>
__attribute__((target("popcnt"))) int hamming_min_popcnt(const uint8_t* q, const uint8_t* rows, int64_t n, int bytes) {
  return hamming_min_body<kWords>(q, rows, n, bytes);
}

template <int kWords>
int hamming_min_generic(const uint8_t* q, const uint8_t* rows, int64_t n, int bytes) {
  return hamming_min_body<kWords>(q, rows, n, bytes);
}

}  // namespace

int hamming_min(const uint8_t* q, const uint8_t* rows, int64_t n, int bytes) {
  static const bool has_popcnt = __builtin_cpu_supports("popcnt");
  if (has_popcnt) {
    switch (bytes) {
      case 32: return hamming_min_popcnt<4>(q, rows, n, bytes);
      case 64: return hamming_min_popcnt<8>(q, rows, n, bytes);
      default: return hamming_min_popcnt<0>(q, rows, n, bytes);
    }
  }
  switch (bytes) {
    case 32: return hamming_min_generic<4>(q, rows, n, bytes);
    case 64: return hamming_min_generic<8>(q, rows, n, bytes);
    default: return hamming_min_generic<0>(q, rows, n, bytes);
  }
}

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
