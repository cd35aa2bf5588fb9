#include "train/boost/negative_miner.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

namespace {

constexpr uint64_t kNegativeTag = 0x4E45474154495645ull;  // bootstrapped negatives

// Uniform index in [0, n) from 64 random bits.
inline uint64_t scale_to(uint64_t bits, uint64_t n) {
  __extension__ typedef unsigned __int128 u128;
  return static_cast<uint64_t>((static_cast<u128>(bits) * n) >> 64);
}

}  // namespace

NegativeMiner::NegativeMiner(const TrainingSet& set, const BoostOptions& options)
    : set_(set), options_(options), C1_(set.num_classes_with_background()) {
  negative_unit_.assign(static_cast<size_t>(C1_), 1.0);
}

double NegativeMiner::sample_weight(int64_t s) const {
  return set_.sample_weight.empty() ? 1.0 : static_cast<double>(set_.sample_weight[s]);
}

bool NegativeMiner::excluded(int32_t c, int64_t s) const {
  const double radius = options_.negatives.exclusion_radius;
  if (c >= set_.num_classes || radius <= 0.0) return false;
  const Eigen::Vector3f& p = set_.sample_position[s];
  if (!p.allFinite()) return false;
  return (p.cast<double>() - set_.class_position[c]).norm() < radius;
}

std::vector<int64_t> NegativeMiner::draw(int32_t c, const std::vector<const std::vector<int64_t>*>& lists,
                                         int32_t n_neg) const {
  std::vector<int64_t> prefix(1, 0);
  for (const auto* l : lists) prefix.push_back(prefix.back() + static_cast<int64_t>(l->size()));
  const int64_t M = prefix.back();
  const uint64_t seed = options_.seed;
  auto accept = [&](int64_t s) { return set_.sample_class[s] != c && !excluded(c, s); };
  std::vector<int64_t> chosen;
  if (M <= 4 * static_cast<int64_t>(n_neg) + 64) {
    // Few candidates: the n_neg with the smallest hashes.
    std::vector<std::pair<uint64_t, int64_t>> keyed;
    for (const auto* l : lists) {
      for (int64_t s : *l) {
        if (accept(s))
          keyed.emplace_back(counter_hash(seed, kNegativeTag, static_cast<uint64_t>(c), static_cast<uint64_t>(s)), s);
      }
    }
    const size_t take = std::min(keyed.size(), static_cast<size_t>(n_neg));
    std::partial_sort(keyed.begin(), keyed.begin() + static_cast<int64_t>(take), keyed.end());
    for (size_t i = 0; i < take; ++i) chosen.push_back(keyed[i].second);
  } else {
    // Many: seeded draws over the concatenated lists, duplicates and refused samples skipped.
    const int64_t attempts = 16 * static_cast<int64_t>(n_neg) + 64;
    for (int64_t a = 0; a < attempts && static_cast<int32_t>(chosen.size()) < n_neg; ++a) {
      const uint64_t r =
          counter_hash(seed, kNegativeTag, static_cast<uint64_t>(c), static_cast<uint64_t>(a) | (1ull << 63));
      const int64_t idx = static_cast<int64_t>(scale_to(r, static_cast<uint64_t>(M)));
      const size_t li = static_cast<size_t>(std::upper_bound(prefix.begin(), prefix.end(), idx) - prefix.begin() - 1);
      const int64_t s = (*lists[li])[idx - prefix[li]];
      if (!accept(s) || std::find(chosen.begin(), chosen.end(), s) != chosen.end()) continue;
      chosen.push_back(s);
    }
  }
  std::sort(chosen.begin(), chosen.end());
  return chosen;
}

void NegativeMiner::bootstrap(EntryStore* entries) {
  const int32_t C = set_.num_classes;
  const int64_t S = set_.num_samples();
  std::vector<std::vector<int64_t>> positives(static_cast<size_t>(C1_));
  int32_t max_word = -1;
  for (int64_t s = 0; s < S; ++s) {
    if (set_.sample_is_validation[s]) continue;
    positives[set_.sample_class[s]].push_back(s);
    max_word = std::max(max_word, set_.sample_word[s]);
  }
  std::vector<std::vector<int64_t>> word_samples(static_cast<size_t>(max_word + 1));
  std::vector<int64_t> all_train, landmark_train;
  for (int64_t s = 0; s < S; ++s) {
    if (set_.sample_is_validation[s]) continue;
    if (set_.sample_word[s] >= 0) word_samples[set_.sample_word[s]].push_back(s);
    all_train.push_back(s);
    if (set_.sample_class[s] < C) landmark_train.push_back(s);
  }
  std::vector<int64_t> samples;
  std::vector<int32_t> codes;
  std::vector<double> weights;
  std::vector<const std::vector<int64_t>*> lists;
  negative_unit_.assign(static_cast<size_t>(C1_), 1.0);
  for (int32_t c = 0; c < C1_; ++c) {
    double positive_total = 0.0;
    for (int64_t s : positives[c]) {
      samples.push_back(s);
      codes.push_back(c * 2);
      weights.push_back(sample_weight(s));
      positive_total += sample_weight(s);
    }
    // Candidates: the background's are the landmark samples; a landmark's share a visual word
    // with one of its positives (every training sample when it has no word).
    lists.clear();
    int32_t n_neg = options_.negatives.per_class;
    if (c == C) {
      lists.push_back(&landmark_train);
      n_neg = options_.negatives.background > 0
                  ? options_.negatives.background
                  : static_cast<int32_t>(std::min<size_t>(landmark_train.size(), std::numeric_limits<int32_t>::max()));
    } else {
      std::vector<int32_t> words;
      for (int64_t s : positives[c]) {
        if (set_.sample_word[s] >= 0) words.push_back(set_.sample_word[s]);
      }
      std::sort(words.begin(), words.end());
      words.erase(std::unique(words.begin(), words.end()), words.end());
      for (int32_t w : words) lists.push_back(&word_samples[w]);
      if (words.empty()) lists.push_back(&all_train);
    }
    const std::vector<int64_t> chosen = draw(c, lists, n_neg);
    // Balanced classes: the negatives share negatives.weight_ratio x the positives' total weight.
    double negative_total = 0.0;
    for (int64_t s : chosen) negative_total += sample_weight(s);
    if (options_.negatives.weight_ratio > 0.0 && negative_total > 0.0 && positive_total > 0.0) {
      negative_unit_[c] = options_.negatives.weight_ratio * positive_total / negative_total;
    }
    for (int64_t s : chosen) {
      samples.push_back(s);
      codes.push_back(c * 2 + 1);
      weights.push_back(negative_unit_[c] * sample_weight(s));
    }
  }
  entries->assign(samples, codes, weights, 0);
}

std::vector<NegativeMiner::Offer> NegativeMiner::pool_offers(TrackedRows& rows) const {
  // Per pool row: the classes ranked at or above the true one, best first.
  const int32_t per_sample = options_.mining.per_sample;
  const std::vector<double>& offset = rows.class_offset();
  std::vector<Offer> offers;
  std::vector<std::pair<float, int32_t>> top;
  rows.for_each_pool_row([&](int64_t r, int64_t s, const float* row) {
    const int32_t y = set_.sample_class[s];
    const double sy = offset[y] + row[y];
    top.clear();
    for (int32_t c = 0; c < C1_; ++c) {
      if (c == y) continue;
      const float sc = static_cast<float>(offset[c] + row[c]);
      if (sc < sy) continue;
      if (static_cast<int32_t>(top.size()) == per_sample && !(sc > top.back().first)) continue;
      auto pos = std::find_if(top.begin(), top.end(), [&](const auto& t) { return sc > t.first; });
      top.insert(pos, {sc, c});
      if (static_cast<int32_t>(top.size()) > per_sample) top.pop_back();
    }
    for (const auto& [sc, c] : top) offers.push_back({r, c, sc});
  });
  return offers;
}

int64_t NegativeMiner::mine(TrackedRows& rows, Collectives& comm, EntryStore* entries) {
  std::vector<Offer> offers = pool_offers(rows);
  // Every rank's offers, by row (a rank's are by row, best first within a row), then the same
  // sequential admission on every rank: the caps make the order matter.
  {
    std::vector<uint8_t> bytes(offers.size() * sizeof(Offer));
    if (!offers.empty()) std::memcpy(bytes.data(), offers.data(), bytes.size());
    std::vector<int64_t> offsets;
    bytes = comm.allgather_bytes(bytes, &offsets);
    LMB_CHECK(bytes.size() % sizeof(Offer) == 0, "boost: mining offers of " << bytes.size() << " bytes are torn");
    offers.resize(bytes.size() / sizeof(Offer));
    if (!offers.empty()) std::memcpy(offers.data(), bytes.data(), bytes.size());
    std::stable_sort(offers.begin(), offers.end(), [](const Offer& a, const Offer& b) { return a.row < b.row; });
  }
  // The negative sets, ascending samples per class.
  std::vector<std::vector<int64_t>> negatives(static_cast<size_t>(C1_));
  for (int64_t s = 0; s < entries->num_samples(); ++s) {
    for (int64_t e = entries->sample_begin()[s]; e < entries->sample_begin()[s + 1]; ++e) {
      if (entries->code(e) & 1) negatives[entries->code(e) >> 1].push_back(s);
    }
  }
  const double log_scale = static_cast<double>(entries->weight_exponent()) * std::log(2.0);
  std::vector<int64_t> new_samples;
  std::vector<int32_t> new_codes;
  std::vector<double> new_weights;
  for (const Offer& offer : offers) {
    const int64_t s = rows.sample(offer.row);
    const int32_t c = offer.cls;
    auto& negs = negatives[c];
    if (static_cast<int32_t>(negs.size()) >= options_.negatives.max_per_class) continue;
    auto it = std::lower_bound(negs.begin(), negs.end(), s);
    if (it != negs.end() && *it == s) continue;
    if (excluded(c, s)) continue;
    negs.insert(it, s);
    new_samples.push_back(s);
    new_codes.push_back(c * 2 + 1);
    // A negative's weight is its initial weight times exp(-z H) = exp(H(s, c)), stored relative
    // to 2^weight_exponent: the weight it would have had in L-_c from the start.
    new_weights.push_back(negative_unit_[c] * sample_weight(s) *
                          std::exp(static_cast<double>(offer.score) - log_scale));
  }
  entries->append(new_samples, new_codes, new_weights);
  return static_cast<int64_t>(new_samples.size());
}

void NegativeMiner::check(const LearnerState& st) const {
  LMB_CHECK(static_cast<int64_t>(st.negative_unit.size()) == C1_,
            "learner state: " << st.negative_unit.size() << " negative weights for " << C1_ << " classes");
  for (double u : st.negative_unit) {
    LMB_CHECK(std::isfinite(u) && u > 0.0, "learner state: negative weight " << u);
  }
}

}  // namespace lmb
