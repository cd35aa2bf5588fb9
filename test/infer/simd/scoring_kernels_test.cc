// The scoring kernels of every SIMD level this CPU runs (infer/simd/scoring_kernels.h) against
// the generic kernels on the same inputs, bit for bit, and the generic kernels against scalar
// references: odd sizes and list lengths (tails of every vector width), extreme values (infinite
// and subnormal stump outputs, sums that overflow, int16 steps at their limits, saturated goals).
#include "infer/simd/scoring_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/random.h"
#include "common/simd/simd_level.h"

namespace lmb {
namespace {

using detail::DenseStump;
using detail::GroupItem;
using detail::ScoringKernels;
using detail::ScreenList;
constexpr int32_t B = detail::kScoringBatch;

std::vector<const ScoringKernels*> fast_kernels() {
  std::vector<const ScoringKernels*> out;
  for (SimdLevel l : compiled_simd_levels()) {
    if (l != SimdLevel::kGeneric && simd_level_supported(l)) out.push_back(detail::scoring_kernels(l));
  }
  return out;
}

const ScoringKernels& generic() { return *detail::scoring_kernels(SimdLevel::kGeneric); }

std::vector<const ScoringKernels*> all_kernels() {
  std::vector<const ScoringKernels*> out = fast_kernels();
  out.insert(out.begin(), &generic());
  return out;
}

uint64_t bits_of(double x) {
  uint64_t b;
  std::memcpy(&b, &x, sizeof(b));
  return b;
}

// A stump output: ordinary values mostly, sometimes an extreme one.
double random_output(Rng& rng, bool extremes) {
  if (extremes) {
    switch (rng.below(10)) {
      case 0: return std::numeric_limits<double>::infinity();
      case 1: return -std::numeric_limits<double>::infinity();
      case 2: return std::numeric_limits<double>::denorm_min() * static_cast<double>(rng.below(1000));
      case 3: return -0.0;
      case 4: return 1e308 * rng.uniform(-1, 1);
      default: break;
    }
  }
  return rng.uniform(-1, 1) * std::pow(10.0, rng.uniform(-12, 3));
}

std::vector<DenseStump> random_stumps(Rng& rng, int32_t num_stumps, int32_t num_used, bool extremes) {
  std::vector<DenseStump> stumps(static_cast<size_t>(num_stumps));
  for (DenseStump& s : stumps) {
    s.used = static_cast<int32_t>(rng.below(static_cast<uint64_t>(num_used)));
    const uint64_t t = rng.below(4);
    s.theta = t == 0 ? 0 : t == 1 ? 254 : static_cast<uint8_t>(rng.below(255));
    s.above = random_output(rng, extremes);
    s.below = random_output(rng, extremes);
  }
  return stumps;
}

// Values of num_used dims for 32 lanes at values[u * stride]: 0, 254, 255 and random bytes.
std::vector<uint8_t> random_values(Rng& rng, int32_t num_used, size_t stride) {
  std::vector<uint8_t> values(static_cast<size_t>(num_used) * stride + B);
  for (uint8_t& v : values) {
    const uint64_t t = rng.below(6);
    v = t == 0 ? 0 : t == 1 ? 255 : t == 2 ? 254 : static_cast<uint8_t>(rng.below(256));
  }
  return values;
}

TEST(ScoringKernels, FireMasksEqualTheByteComparisonsAtEveryLevel) {
  Rng rng(5);
  for (size_t stride : {size_t{32}, size_t{37}, size_t{100}}) {
    for (int32_t num_stumps : {0, 1, 17, 300}) {
      const int32_t num_used = 23;
      const std::vector<DenseStump> stumps = random_stumps(rng, num_stumps, num_used, false);
      const std::vector<uint8_t> values = random_values(rng, num_used, stride);
      std::vector<uint32_t> want(static_cast<size_t>(num_stumps) + 1, 0xDEADBEEF);
      generic().fire_masks(stumps.data(), stumps.size(), values.data(), stride, want.data());
      for (int32_t s = 0; s < num_stumps; ++s) {
        for (int32_t j = 0; j < B; ++j) {
          const bool fires = values[stumps[s].used * stride + j] > stumps[s].theta;
          ASSERT_EQ((want[s] >> j) & 1, fires ? 1u : 0u) << "stump " << s << " lane " << j;
        }
      }
      EXPECT_EQ(want[num_stumps], 0xDEADBEEFu);  // nothing written past the end
      for (const ScoringKernels* k : fast_kernels()) {
        std::vector<uint32_t> got(want.size(), 0xDEADBEEF);
        k->fire_masks(stumps.data(), stumps.size(), values.data(), stride, got.data());
        ASSERT_EQ(got, want) << simd_level_name(k->level) << " stride " << stride << " stumps " << num_stumps;
      }
    }
  }
}

// bias + the lane's outputs in list order, the reference of every accumulation.
double reference_sum(double bias, const std::vector<int32_t>& list, const std::vector<DenseStump>& stumps,
                     const std::vector<uint32_t>& fire, int32_t lane) {
  double total = bias;
  for (int32_t s : list) total += (fire[s] >> lane) & 1 ? stumps[s].above : stumps[s].below;
  return total;
}

TEST(ScoringKernels, AccumulationsEqualTheListOrderSumAtEveryLevel) {
  Rng rng(6);
  const int32_t num_stumps = 400;
  for (bool extremes : {false, true}) {
    const std::vector<DenseStump> stumps = random_stumps(rng, num_stumps, 10, extremes);
    std::vector<uint32_t> fire(num_stumps);
    for (uint32_t& f : fire) {
      const uint64_t t = rng.below(5);
      f = t == 0 ? 0u : t == 1 ? ~0u : static_cast<uint32_t>(rng.next());
    }
    for (int trial = 0; trial < 40; ++trial) {
      auto random_list = [&] {
        const int64_t lengths[] = {0, 1, 2, 7, 33, 64, 65, 250};
        std::vector<int32_t> list(static_cast<size_t>(trial < 8 ? lengths[trial] : lengths[rng.below(8)]));
        for (int32_t& s : list) s = static_cast<int32_t>(rng.below(num_stumps));
        return list;
      };
      const std::vector<int32_t> list0 = random_list(), list1 = random_list();
      const int64_t n0 = static_cast<int64_t>(list0.size()), n1 = static_cast<int64_t>(list1.size());
      const double bias0 = random_output(rng, extremes), bias1 = rng.uniform(-5, 5);
      std::vector<double> lanes(B), two0(B), two1(B);
      generic().accumulate_lanes(bias0, list0.data(), n0, stumps.data(), fire.data(), lanes.data());
      generic().accumulate_two(bias0, list0.data(), n0, bias1, list1.data(), n1, stumps.data(), fire.data(),
                               two0.data(), two1.data());
      for (int32_t j = 0; j < B; ++j) {
        ASSERT_EQ(bits_of(lanes[j]), bits_of(reference_sum(bias0, list0, stumps, fire, j))) << "lane " << j;
        ASSERT_EQ(bits_of(two0[j]), bits_of(lanes[j]));
        ASSERT_EQ(bits_of(two1[j]), bits_of(reference_sum(bias1, list1, stumps, fire, j)));
      }
      // Groups: 0 to 9 items (not a multiple of the four a pass takes), lists of both lengths.
      const int32_t num_items = trial % 10;
      std::vector<double> grouped(8 * static_cast<size_t>(num_items) + 1, 7.0);
      std::vector<GroupItem> items;
      for (int32_t i = 0; i < num_items; ++i) {
        const bool first = (i + trial) % 3 != 0;
        items.push_back({first ? bias0 : bias1, first ? list0.data() : list1.data(), first ? n0 : n1,
                         static_cast<int32_t>(rng.below(4)), grouped.data() + 8 * i});
      }
      generic().accumulate_groups(items.data(), num_items, stumps.data(), fire.data());
      for (int32_t i = 0; i < num_items; ++i) {
        const std::vector<int32_t>& list = items[i].stumps == list0.data() ? list0 : list1;
        for (int32_t l = 0; l < 8; ++l) {
          ASSERT_EQ(bits_of(grouped[8 * i + l]),
                    bits_of(reference_sum(items[i].bias, list, stumps, fire, 8 * items[i].group + l)));
        }
      }
      ASSERT_EQ(grouped.back(), 7.0);
      for (const ScoringKernels* k : fast_kernels()) {
        const char* name = simd_level_name(k->level);
        std::vector<double> got(B), got0(B), got1(B);
        k->accumulate_lanes(bias0, list0.data(), n0, stumps.data(), fire.data(), got.data());
        k->accumulate_two(bias0, list0.data(), n0, bias1, list1.data(), n1, stumps.data(), fire.data(), got0.data(),
                          got1.data());
        for (int32_t j = 0; j < B; ++j) {
          ASSERT_EQ(bits_of(got[j]), bits_of(lanes[j])) << name << " trial " << trial << " lane " << j;
          ASSERT_EQ(bits_of(got0[j]), bits_of(two0[j])) << name << " trial " << trial << " lane " << j;
          ASSERT_EQ(bits_of(got1[j]), bits_of(two1[j])) << name << " trial " << trial << " lane " << j;
        }
        std::vector<double> got_grouped(grouped.size(), 7.0);
        std::vector<GroupItem> got_items = items;
        for (int32_t i = 0; i < num_items; ++i) got_items[i].out = got_grouped.data() + 8 * i;
        k->accumulate_groups(got_items.data(), num_items, stumps.data(), fire.data());
        for (size_t i = 0; i < grouped.size(); ++i) {
          ASSERT_EQ(bits_of(got_grouped[i]), bits_of(grouped[i])) << name << " trial " << trial << " entry " << i;
        }
      }
    }
  }
}

// The generic screening of one batch, written out lane by lane from model.h's definition.
// residues (B entries) gets each lane's residue at the end of the list when some lane passes there.
uint32_t reference_screen(const ScreenList& v, const uint32_t* fire, const int32_t* goal, uint32_t valid,
                          uint16_t* residues) {
  uint32_t sums[B] = {};
  for (int64_t e = 0, k = 0;; ++k) {
    const int64_t stop = std::min<int64_t>(v.count, e + detail::kScreenCheck);
    for (; e < stop; ++e) {
      for (int32_t j = 0; j < B; ++j) {
        if ((fire[v.list[e]] >> j) & 1) sums[j] = (sums[j] + static_cast<uint16_t>(v.q[v.list[e]])) & 0xFFFF;
      }
    }
    const bool last = e == v.count;
    const uint32_t low = last ? v.end_low : v.check_low[k];
    const int64_t shift = (last ? 0 : v.check_add[k]) + int64_t{v.units} + 2;
    uint32_t bits = 0;
    for (int32_t j = 0; j < B; ++j) {
      const int64_t t = (sums[j] - low) & 0xFFFF;
      const int64_t threshold = std::clamp<int64_t>(goal[j] - shift, 0, 65535);
      if (t >= threshold) bits |= 1u << j;
    }
    bits &= valid;
    if (last && bits != 0) {
      for (int32_t j = 0; j < B; ++j) residues[j] = static_cast<uint16_t>((sums[j] - low) & 0xFFFF);
    }
    if (last || bits == 0) return bits;
  }
}

TEST(ScoringKernels, ScreeningEqualsTheLaneByLaneDefinitionAtEveryLevel) {
  Rng rng(7);
  const int32_t num_stumps = 300;
  std::vector<int16_t> q(num_stumps);
  for (int16_t& x : q) {
    const uint64_t t = rng.below(8);
    x = t == 0   ? int16_t{32767}
        : t == 1 ? int16_t{-32768}
        : t == 2 ? int16_t{0}
                 : static_cast<int16_t>(rng.below(65536));
  }
  int tested = 0, passed = 0, kept_one_batch = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const int64_t lengths[] = {0, 1, 31, 32, 33, 64, 65, 200};
    std::vector<uint16_t> list(static_cast<size_t>(lengths[trial % 8]));
    for (uint16_t& s : list) s = static_cast<uint16_t>(rng.below(num_stumps));
    const size_t checks = list.size() / detail::kScreenCheck + 1;
    std::vector<uint16_t> check_low(checks);
    std::vector<int32_t> check_add(checks);
    for (size_t i = 0; i < checks; ++i) {
      check_low[i] = static_cast<uint16_t>(rng.below(65536));
      check_add[i] = static_cast<int32_t>(rng.below(70000));
    }
    ScreenList v;
    v.q = q.data();
    v.list = list.data();
    v.count = static_cast<int64_t>(list.size());
    v.check_low = check_low.data();
    v.check_add = check_add.data();
    v.end_low = static_cast<uint16_t>(rng.below(65536));
    const int32_t units[] = {0, -(1 << 29), 1 << 29, -70000, 70000};
    v.units = trial % 3 == 0 ? units[rng.below(5)] : static_cast<int32_t>(rng.below(140000)) - 70000;
    std::vector<uint32_t> fire0(num_stumps), fire1(num_stumps);
    for (uint32_t& f : fire0) f = static_cast<uint32_t>(rng.next());
    for (uint32_t& f : fire1) f = rng.below(2) ? static_cast<uint32_t>(rng.next()) : 0u;
    std::vector<int32_t> goal0(B), goal1(B);
    // Goals: mixed (the pass-all goal, a saturated one, ordinary ones), or all saturated (a lane
    // then passes only with a residue of 65535).
    for (std::vector<int32_t>* g : {&goal0, &goal1}) {
      for (int32_t& x : *g) {
        const uint64_t t = trial % 4 == 3 ? 1 : rng.below(8);
        x = t == 0 ? -(1 << 29) - 2 : t == 1 ? (1 << 29) : static_cast<int32_t>(rng.below(200000)) - 100000 + v.units;
      }
    }
    const uint32_t valid[2] = {trial % 5 == 0 ? (1u << (trial % 31)) - 1 : ~0u, trial % 7 == 0 ? 0u : ~0u};
    const uint32_t* fire[2] = {fire0.data(), fire1.data()};
    const int32_t* goal[2] = {goal0.data(), goal1.data()};
    uint16_t want_residues[2 * B] = {};
    const uint32_t want0 = reference_screen(v, fire0.data(), goal0.data(), valid[0], want_residues);
    const uint32_t want1 = reference_screen(v, fire1.data(), goal1.data(), valid[1], want_residues + B);
    const uint64_t want = want0 | static_cast<uint64_t>(want1) << 32;
    // The bits, without residues and with them; the residues of each batch with a lane kept (the
    // others' slots are left as they were).
    const auto check = [&](const ScoringKernels& k, int32_t batches, int32_t first, uint64_t expected) {
      const std::string where = std::string(simd_level_name(k.level)) + " trial " + std::to_string(trial) +
                                " batches " + std::to_string(batches) + " first " + std::to_string(first);
      ASSERT_EQ(k.screen_class(v, batches, fire + first, goal + first, valid + first, nullptr), expected) << where;
      uint16_t residues[2 * B];
      std::fill(residues, residues + 2 * B, uint16_t{0xABCD});
      ASSERT_EQ(k.screen_class(v, batches, fire + first, goal + first, valid + first, residues), expected) << where;
      for (int32_t b = 0; b < batches; ++b) {
        const bool kept = ((expected >> (32 * b)) & 0xFFFFFFFFu) != 0;
        for (int32_t j = 0; j < B; ++j) {
          ASSERT_EQ(residues[B * b + j], kept ? want_residues[B * (first + b) + j] : uint16_t{0xABCD})
              << where << " batch " << b << " lane " << j;
        }
      }
    };
    for (const ScoringKernels* k : all_kernels()) {
      check(*k, 2, 0, want);
      check(*k, 1, 0, want0);
      check(*k, 1, 1, want1);
    }
    ++tested;
    passed += want != 0;
    kept_one_batch += (want0 != 0) != (want1 != 0);
  }
  // Both outcomes occur, and pairs where one batch is dropped and the other goes on alone.
  EXPECT_GT(passed, 0);
  EXPECT_LT(passed, tested);
  EXPECT_GT(kept_one_batch, 0);
}

TEST(ScoringKernels, LaneTestEqualsTheScalarTestsAtEveryLevel) {
  Rng rng(8);
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double specials[] = {inf, -inf, nan, 0.0, -0.0, 1e308, -1e308};
  int any = 0;
  for (int trial = 0; trial < 400; ++trial) {
    std::vector<double> score(B), background(B), cutoff(B);
    // Every fifth trial: scores far below the backgrounds and cutoffs (no lane passes unless a
    // special value or an infinite margin lets it).
    const double low = trial % 5 == 0 ? -40.0 : 0.0;
    for (int32_t j = 0; j < B; ++j) {
      score[j] = rng.below(8) == 0 ? specials[rng.below(7)] : low + rng.uniform(-3, 3);
      background[j] = rng.below(8) == 0 ? specials[rng.below(7)] : rng.uniform(-1, 1) + 2.5;
      cutoff[j] = rng.below(2) ? -inf : rng.uniform(-3, 3);
    }
    const double margins[] = {0.0, -inf, -1.0, 0.5};
    const double floors[] = {-inf, 0.0, -2.0};
    const double margin = margins[trial % 4], floor = floors[trial % 3];
    bool want = false;
    for (int32_t j = 0; j < B; ++j) {
      want = want || (score[j] - background[j] > margin && score[j] >= floor && score[j] >= cutoff[j]);
    }
    ASSERT_EQ(generic().any_lane_passes(score.data(), background.data(), cutoff.data(), margin, floor), want);
    for (const ScoringKernels* k : fast_kernels()) {
      ASSERT_EQ(k->any_lane_passes(score.data(), background.data(), cutoff.data(), margin, floor), want)
          << simd_level_name(k->level) << " trial " << trial;
    }
    any += want;
  }
  // Both outcomes occur.
  EXPECT_GT(any, 20);
  EXPECT_LT(any, 390);
}

}  // namespace
}  // namespace lmb
