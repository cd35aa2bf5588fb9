#include "train/boost/column_screener.h"

#include <emmintrin.h>

#include <chrono>
#include <cstring>

#include "common/cpu_dispatch.h"
#include "common/error.h"
#include "train/boost/screening_gain.h"

namespace lmb {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

using screening::V4d;
using screening::V4l;

// The kernel's groups of one dim: thresholds 4 i .. 4 i + 3 in chunk i.
struct BlockGroups {
  screening::Groups<V4d> chunk[4];
};

// Adds one class to the groups of thresholds 0 .. 4 * chunks - 1 of a dim, given the class's
// per-bucket sums of positive and negative weight (buckets 0..15; bucket b holds the samples with
// b thresholds below their value): the sums above each threshold, four thresholds at a time. Every
// sum is an integer below 2^52 (EntryStore::quantize), so the int64 -> double conversion (by the
// 2^52 exponent trick) and the sums above each threshold are exact, as in a column pass.
LMB_CLONES_AVX2 void add_class_to_block(const int64_t* bucket_p, const int64_t* bucket_n, int32_t chunks,
                                        int64_t class_w, int64_t class_y, double class_q, BlockGroups* g) {
  const V4d zero = {0, 0, 0, 0};
  const V4l magic_bits = {0x4330000000000000, 0x4330000000000000, 0x4330000000000000, 0x4330000000000000};
  const double two52 = 4503599627370496.0;
  const V4d magic = {two52, two52, two52, two52};
  // (In place, not by value: 32-byte vectors in a function's signature change its ABI without AVX.)
  auto to_double = [&](const int64_t* x, V4d* d) {  // exact for 0 <= x < 2^52
    const V4l bits = *reinterpret_cast<const V4l*>(x) | magic_bits;
    std::memcpy(d, &bits, sizeof(*d));
    *d -= magic;
  };
  // Inclusive prefix sums of a chunk: [a0, a0+a1, a0+a1+a2, a0+..+a3] (__builtin_shufflevector: GCC >= 12
  // and clang, which builds the fuzz targets).
  auto prefix = [&](V4d* x) {
    *x += __builtin_shufflevector(*x, zero, 4, 0, 1, 2);
    *x += __builtin_shufflevector(*x, zero, 4, 4, 0, 1);
  };
  V4d incl_p[4], incl_n[4];
  V4d carry_p = zero, carry_n = zero;
  for (int32_t i = 0; i < 4; ++i) {
    to_double(bucket_p + 4 * i, &incl_p[i]);
    to_double(bucket_n + 4 * i, &incl_n[i]);
    prefix(&incl_p[i]);
    prefix(&incl_n[i]);
    incl_p[i] += carry_p;
    incl_n[i] += carry_n;
    carry_p = __builtin_shufflevector(incl_p[i], incl_p[i], 3, 3, 3, 3);
    carry_n = __builtin_shufflevector(incl_n[i], incl_n[i], 3, 3, 3, 3);
  }
  const double cw = static_cast<double>(class_w), cy = static_cast<double>(class_y);
  const V4d q = {class_q, class_q, class_q, class_q};
  for (int32_t i = 0; i < chunks; ++i) {
    const V4d p = carry_p - incl_p[i], n = carry_n - incl_n[i];  // above threshold t: buckets t+1..15
    const V4d wp = p + n, yp = p - n;
    const V4d wm = cw - wp, ym = cy - yp;
    g->chunk[i].add(wp, yp, wm, ym, q);
  }
}

// packed[i] = the bucket of sample i in column k (the number of its thresholds below the value)
// in bits 4k..4k+3, for k < count (<= 8); higher bits 0. Sixteen samples at a time with SSE2:
// bucket = sum over thresholds of [v > t], then a 4 x 16 byte transpose of the nibble pairs.
void pack_buckets(const uint8_t* const* cols, const uint8_t* const* thresholds, const int32_t* T, int32_t count,
                  int64_t S, uint32_t* packed) {
  int64_t i = 0;
  for (; i + 16 <= S; i += 16) {
    __m128i nib[4];
    for (int j = 0; j < 4; ++j) {
      __m128i pair[2] = {_mm_setzero_si128(), _mm_setzero_si128()};
      for (int h = 0; h < 2; ++h) {
        const int k = 2 * j + h;
        if (k >= count) continue;
        const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(cols[k] + i));
        __m128i b = _mm_setzero_si128();
        for (int32_t t = 0; t < T[k]; ++t) {
          const __m128i above = _mm_set1_epi8(static_cast<char>(thresholds[k][t] + 1));
          b = _mm_sub_epi8(b, _mm_cmpeq_epi8(_mm_max_epu8(v, above), v));  // v > t: -1
        }
        pair[h] = b;
      }
      nib[j] = _mm_or_si128(pair[0], _mm_slli_epi16(pair[1], 4));  // buckets <= 15: no carry
    }
    const __m128i lo01 = _mm_unpacklo_epi8(nib[0], nib[1]), hi01 = _mm_unpackhi_epi8(nib[0], nib[1]);
    const __m128i lo23 = _mm_unpacklo_epi8(nib[2], nib[3]), hi23 = _mm_unpackhi_epi8(nib[2], nib[3]);
    __m128i* out = reinterpret_cast<__m128i*>(packed + i);
    _mm_storeu_si128(out + 0, _mm_unpacklo_epi16(lo01, lo23));
    _mm_storeu_si128(out + 1, _mm_unpackhi_epi16(lo01, lo23));
    _mm_storeu_si128(out + 2, _mm_unpacklo_epi16(hi01, hi23));
    _mm_storeu_si128(out + 3, _mm_unpackhi_epi16(hi01, hi23));
  }
  for (; i < S; ++i) {
    uint32_t u = 0;
    for (int32_t k = 0; k < count; ++k) {
      uint32_t b = 0;
      for (int32_t t = 0; t < T[k]; ++t) b += cols[k][i] > thresholds[k][t];
      u |= b << (4 * k);
    }
    packed[i] = u;
  }
}

// The per-(dim, bucket) positive (side 0) and negative (side 1) weight of one class's entries
// [begin, mid) and [mid, end) of the class-major copy, for the K dims packed in `packed`.
template <int K>
inline void bucket_class(const uint32_t* packed, const int32_t* sample, const int64_t* wq, int64_t begin, int64_t mid,
                         int64_t end, int64_t (&acc)[2][K][16]) {
  // Two copies of the per-class buckets, for even and odd entries: consecutive entries often hit
  // the same bucket, and one copy would chain each add to the previous one's store.
  alignas(64) int64_t acc2[2][K][16];
  std::memset(acc, 0, sizeof(acc));
  std::memset(acc2, 0, sizeof(acc2));
  for (int side = 0; side < 2; ++side) {
    int64_t(*a)[16] = acc[side];
    int64_t(*b)[16] = acc2[side];
    int64_t e = side ? mid : begin;
    const int64_t e1 = side ? end : mid;
    for (; e + 2 <= e1; e += 2) {
      __builtin_prefetch(packed + sample[e + 16]);  // class_sample() has 32 samples of padding
      __builtin_prefetch(packed + sample[e + 17]);
      const uint32_t u = packed[sample[e]], v = packed[sample[e + 1]];
      const int64_t w = wq[e], x = wq[e + 1];
      for (int k = 0; k < K; ++k) {
        a[k][(u >> (4 * k)) & 15u] += w;
        b[k][(v >> (4 * k)) & 15u] += x;
      }
    }
    if (e < e1) {
      const uint32_t u = packed[sample[e]];
      for (int k = 0; k < K; ++k) a[k][(u >> (4 * k)) & 15u] += wq[e];
    }
    for (int k = 0; k < K; ++k) {
      for (int j = 0; j < 16; ++j) a[k][j] += b[k][j];
    }
  }
}

}  // namespace

ColumnScreener::ColumnScreener(const EntryStore& entries) : entries_(entries) {}

void ColumnScreener::scatter(const FeatureColumns::Ref& ref) {
  const FeatureColumns::Layout& layout = *ref.layout;
  const uint8_t* col = ref.column;
  const int32_t T = static_cast<int32_t>(layout.thresholds.size());
  const size_t plane = static_cast<size_t>(entries_.num_classes()) * 2;  // one bucket: (P, N) per class
  if (hist_.size() < plane * T) hist_.resize(plane * T, 0);
  const uint8_t* bucket = layout.bucket;
  const int64_t S = entries_.num_samples();
  // Pass 1: the samples above the smallest threshold t0, 16 bins at a time: v > t0 <=> max(v, t0 + 1) == v.
  nonzero_.clear();
  const uint8_t t0 = layout.thresholds[0];
  const __m128i t0p1 = _mm_set1_epi8(static_cast<char>(t0 + 1));
  int64_t s = 0;
  for (; s + 16 <= S; s += 16) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(col + s));
    uint32_t mask = static_cast<uint32_t>(_mm_movemask_epi8(_mm_cmpeq_epi8(_mm_max_epu8(v, t0p1), v)));
    while (mask) {
      const int64_t k = s + __builtin_ctz(mask);
      mask &= mask - 1;
      nonzero_.emplace_back(static_cast<int32_t>(k), bucket[col[k]]);
    }
  }
  for (; s < S; ++s) {
    const int b = bucket[col[s]];
    if (b) nonzero_.emplace_back(static_cast<int32_t>(s), b);
  }
  // Pass 2: scatter their entries' weights into per-(class, bucket) sums, prefetching ahead.
  const int64_t* off = entries_.sample_begin();
  const EntryStore::HotEntry* hot = entries_.hot();
  int64_t* hist = hist_.data();
  const size_t n = nonzero_.size();
  constexpr size_t kAhead = 16;
  constexpr size_t kRowAhead = 8;
  for (size_t i = 0; i < n; ++i) {
    if (i + kAhead < n) __builtin_prefetch(hot + off[nonzero_[i + kAhead].first]);
    if (i + kRowAhead < n) {
      // The entries of sample i + 8 were prefetched 8 iterations ago: prefetch their rows.
      const auto [sa, ba] = nonzero_[i + kRowAhead];
      const size_t base = static_cast<size_t>(ba - 1) * plane;
      for (int64_t e = off[sa]; e < off[sa + 1]; ++e) {
        __builtin_prefetch(hist + base + static_cast<size_t>(hot[e].code >> 1) * 2, 1);
      }
    }
    const auto [sample, b] = nonzero_[i];
    const int64_t end = off[sample + 1];
    int64_t* h = hist + static_cast<size_t>(b - 1) * plane;
    for (int64_t e = off[sample]; e < end; ++e) h[hot[e].code] += hot[e].wq;  // code = 2 c + neg
  }
}

int32_t ColumnScreener::histogram(const FeatureColumns::Ref& ref) {
  scatter(ref);
  // Bucket t becomes the sums above threshold t (buckets t+1..T, stored at t..T-1).
  const int32_t T = static_cast<int32_t>(ref.layout->thresholds.size());
  const size_t plane = static_cast<size_t>(entries_.num_classes()) * 2;
  int64_t* hist = hist_.data();
  for (int32_t t = T - 2; t >= 0; --t) {
    int64_t* dst = hist + static_cast<size_t>(t) * plane;
    const int64_t* src = dst + plane;
    for (size_t i = 0; i < plane; ++i) dst[i] += src[i];
  }
  return T;
}

void ColumnScreener::clear_histogram(int32_t T) {
  std::memset(hist_.data(), 0,
              static_cast<size_t>(entries_.num_classes()) * 2 * static_cast<size_t>(T) * sizeof(int64_t));
}

void ColumnScreener::collect_sums(const FeatureColumns::Ref& ref) {
  const int32_t T = histogram(ref);
  const int32_t C1 = entries_.num_classes();
  const size_t plane = static_cast<size_t>(C1) * 2;
  const int64_t* hist = hist_.data();
  // Classes with any weight above the smallest threshold, ascending.
  touched_.clear();
  for (int32_t c = 0; c < C1; ++c) {
    if (hist[2 * c] | hist[2 * c + 1]) touched_.push_back(c);
  }
  const int32_t m = static_cast<int32_t>(touched_.size());
  cum_p_.resize(static_cast<size_t>(T) * m);
  cum_n_.resize(static_cast<size_t>(T) * m);
  for (int32_t t = 0; t < T; ++t) {
    const int64_t* h = hist + static_cast<size_t>(t) * plane;
    for (int32_t j = 0; j < m; ++j) {
      cum_p_[static_cast<size_t>(t) * m + j] = h[2 * touched_[j]];
      cum_n_[static_cast<size_t>(t) * m + j] = h[2 * touched_[j] + 1];
    }
  }
  clear_histogram(T);
}

void ColumnScreener::screen_column(const FeatureColumns::Ref& ref, bool step, std::vector<double>* gains) {
  const int32_t T = histogram(ref);
  const int32_t C1 = entries_.num_classes();
  const int64_t* hist = hist_.data();
  const int64_t* cw = entries_.class_w().data();
  const int64_t* cy = entries_.class_y().data();
  const double* cq = entries_.class_q().data();
  gains->resize(static_cast<size_t>(T));
  for (int32_t t = 0; t < T; ++t) {
    const int64_t* h = hist + static_cast<size_t>(t) * C1 * 2;
    // The classes with weight above the threshold; the others join no group (the kernel's note).
    // (Measured: branch-free masks over every class were slower than skipping these.)
    (*gains)[t] = screening::screening_gain(
        [&](const auto& add) {
          for (int32_t c = 0; c < C1; ++c) {
            const int64_t p = h[2 * c], n = h[2 * c + 1];
            if ((p | n) == 0) continue;
            add(static_cast<double>(p + n), static_cast<double>(p - n), static_cast<double>(cw[c] - (p + n)),
                static_cast<double>(cy[c] - (p - n)), cq[c]);
          }
        },
        step);
  }
  clear_histogram(T);
}

void ColumnScreener::screen_block(const FeatureColumns::Ref* refs, int32_t count, double* gains) {
  // Why class-major: a column pass touches the entries of every sample above the smallest
  // threshold, ~45% of them on the paper world (median dim), and scatters them across a 1 MB
  // histogram. Here every entry is streamed once per block of kBlockDims dims, reads one packed
  // word of its sample's buckets, and adds into per-class buckets that stay in L1; the screening
  // sums then run per class, for every (dim, threshold) of the block, in the same ascending class
  // order as a column pass, so each group sum sees the same additions in the same order.
  constexpr int K = kBlockDims;
  LMB_CHECK(count >= 1 && count <= K, "boost: screen_block of " << count << " dims");
  const int64_t S = entries_.num_samples();
  packed_buckets_.resize(static_cast<size_t>(S) + 16);  // + the prefetch distance (zeros)
  uint32_t* packed = packed_buckets_.data();
  int32_t T[K] = {0};
  const uint8_t* cols[K];
  const uint8_t* thresholds[K];
  for (int32_t k = 0; k < count; ++k) {
    const FeatureColumns::Layout& layout = *refs[k].layout;
    T[k] = static_cast<int32_t>(layout.thresholds.size());
    LMB_CHECK(T[k] >= 1 && T[k] <= FeatureColumns::kMaxBlockedThresholds,
              "boost: screen_block: dim " << refs[k].dim << " has " << T[k] << " thresholds");
    cols[k] = refs[k].column;
    thresholds[k] = layout.thresholds.data();
  }
  pack_buckets(cols, thresholds, T, count, S, packed);
  std::fill(packed + S, packed + S + 16, 0u);
  alignas(64) BlockGroups groups[K];
  alignas(64) int64_t acc[2][K][16];
  const std::vector<int64_t>& cw = entries_.class_w();
  const std::vector<int64_t>& cy = entries_.class_y();
  const std::vector<double>& cq = entries_.class_q();
  for (int32_t c = 0; c < entries_.num_classes(); ++c) {
    const int64_t begin = entries_.class_begin(c), end = entries_.class_begin(c + 1);
    if (begin == end) continue;
    bucket_class<K>(packed, entries_.class_sample(), entries_.class_wq(), begin, entries_.class_negatives_begin(c), end,
                    acc);
    for (int32_t k = 0; k < count; ++k) {
      add_class_to_block(acc[0][k], acc[1][k], (T[k] + 3) / 4, cw[c], cy[c], cq[c], &groups[k]);
    }
  }
  for (int32_t k = 0; k < count; ++k) {
    for (int32_t t = 0; t < T[k]; ++t) {
      const screening::Groups<V4d>& g = groups[k].chunk[t / 4];
      const int lane = t % 4;
      const double rise[5] = {g.rise[0][lane], g.rise[1][lane], g.rise[2][lane], g.rise[3][lane], g.rise[4][lane]};
      const double fall[5] = {g.fall[0][lane], g.fall[1][lane], g.fall[2][lane], g.fall[3][lane], g.fall[4][lane]};
      gains[k * 16 + t] = std::max(screening::gain_of(rise), screening::gain_of(fall));
    }
  }
}

std::vector<ScreenedCandidate> ColumnScreener::screen(const FeatureColumns& columns,
                                                      const std::vector<int32_t>& sorted_dims, bool step,
                                                      double* pass_seconds) {
  std::vector<ScreenedCandidate> screened;
  auto keep = [&](const FeatureColumns::Ref& ref, const double* gains) {
    const FeatureColumns::Layout& layout = *ref.layout;
    for (size_t t = 0; t < layout.thresholds.size(); ++t) {
      if (gains[t] > 0.0) screened.push_back({gains[t], ref.dim, layout.thresholds[t], layout.above_fraction});
    }
  };
  // Blocked dims are screened kBlockDims at a time; the others get a column pass each.
  std::vector<FeatureColumns::Ref> block;
  auto flush_block = [&] {
    if (block.empty()) return;
    const auto t0 = Clock::now();
    double gains[kBlockDims * 16];
    screen_block(block.data(), static_cast<int32_t>(block.size()), gains);
    *pass_seconds += seconds_since(t0);
    for (size_t k = 0; k < block.size(); ++k) keep(block[k], gains + k * 16);
    block.clear();
  };
  for (int32_t d : sorted_dims) {
    const FeatureColumns::Ref ref = columns.get(d, "screening");
    const FeatureColumns::Kind kind = columns.kind(*ref.layout);
    if (kind == FeatureColumns::kConstant) continue;
    if (kind == FeatureColumns::kBlocked) {
      block.push_back(ref);
      if (static_cast<int32_t>(block.size()) == kBlockDims) flush_block();
      continue;
    }
    const auto t0 = Clock::now();
    screen_column(ref, step, &gains_);
    *pass_seconds += seconds_since(t0);
    keep(ref, gains_.data());
  }
  flush_block();
  return screened;
}

}  // namespace lmb
