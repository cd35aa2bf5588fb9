#include "train/boost/synthetic_problem.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

void SyntheticBoostOptions::check() const {
  LMB_CHECK(num_classes >= 1 && observations_per_class >= 2 && validation_per_class >= 0 &&
                validation_per_class < observations_per_class && num_background >= 1,
            "synthetic problem: bad class/sample counts");
  LMB_CHECK(context_dims >= 1 && descriptor_bits >= 1 && alias_group_size >= 1 && signature_dims >= 0 &&
                signature_dims <= context_dims && num_words >= 1,
            "synthetic problem: bad dimensions");
  LMB_CHECK(noise_density >= 0.0 && noise_density < 1.0 && signature_keep >= 0.0 && signature_keep <= 1.0 &&
                descriptor_flip >= 0.0 && descriptor_flip <= 0.5,
            "synthetic problem: bad probabilities");
}

SyntheticBoostOptions paper_shape_synthetic_options() {
  SyntheticBoostOptions o;
  o.num_classes = 7500;
  o.observations_per_class = 15;
  o.validation_per_class = 2;
  o.num_background = 37500;
  o.context_dims = 16384;
  o.descriptor_bits = 512;
  o.alias_group_size = 4;
  o.signature_dims = 24;
  o.noise_density = 0.15;
  return o;
}

SyntheticBoostProblem make_synthetic_boost_problem(const SyntheticBoostOptions& o) {
  o.check();
  Rng rng(o.seed);
  const int32_t C = o.num_classes;
  const int32_t groups = (C + o.alias_group_size - 1) / o.alias_group_size;
  const int64_t S = static_cast<int64_t>(C) * o.observations_per_class + o.num_background;
  const int32_t D = o.context_dims + o.descriptor_bits;

  SyntheticBoostProblem p;
  p.context_dims = o.context_dims;
  p.descriptor_bits = o.descriptor_bits;
  TrainingSet& set = p.set;
  set.num_classes = C;
  for (int32_t c = 0; c < C; ++c) {
    set.class_landmark.push_back(c);
    set.class_position.emplace_back(rng.uniform(0, 100), rng.uniform(0, 100), rng.uniform(0, 100));
  }
  std::vector<std::vector<uint8_t>> prototype(static_cast<size_t>(groups),
                                              std::vector<uint8_t>(static_cast<size_t>(o.descriptor_bits)));
  std::vector<int32_t> group_word(static_cast<size_t>(groups));
  for (int32_t g = 0; g < groups; ++g) {
    for (auto& b : prototype[g]) b = static_cast<uint8_t>(rng.next() & 1);
    group_word[g] = static_cast<int32_t>(rng.below(static_cast<uint64_t>(o.num_words)));
  }
  std::vector<std::vector<std::pair<int32_t, uint8_t>>> signature(static_cast<size_t>(C));
  for (int32_t c = 0; c < C; ++c) {
    std::vector<int32_t> dims;
    while (static_cast<int32_t>(dims.size()) < o.signature_dims) {
      const int32_t d = static_cast<int32_t>(rng.below(static_cast<uint64_t>(o.context_dims)));
      if (std::find(dims.begin(), dims.end(), d) == dims.end()) dims.push_back(d);
    }
    for (int32_t d : dims) signature[c].emplace_back(d, static_cast<uint8_t>(64 + rng.below(176)));
  }

  // Per-sample labels; sample_group: descriptor prototype (-1 = random descriptor).
  std::vector<int32_t> sample_group(static_cast<size_t>(S));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int32_t c = 0; c < C; ++c) {
    for (int32_t i = 0; i < o.observations_per_class; ++i) {
      set.sample_class.push_back(c);
      set.sample_is_validation.push_back(i < o.validation_per_class ? 1 : 0);
      set.sample_position.push_back(set.class_position[c].cast<float>());
      sample_group[set.sample_class.size() - 1] = c / o.alias_group_size;
    }
  }
  for (int64_t i = 0; i < o.num_background; ++i) {
    set.sample_class.push_back(C);
    set.sample_is_validation.push_back(0);
    set.sample_position.emplace_back(nan, nan, nan);
    sample_group[set.sample_class.size() - 1] =
        (rng.next() & 1) ? static_cast<int32_t>(rng.below(static_cast<uint64_t>(groups))) : -1;
  }
  for (int64_t s = 0; s < S; ++s) {
    const int32_t g = sample_group[s];
    const bool random_word = g < 0 || rng.uniform() < 0.1;
    set.sample_word.push_back(random_word ? static_cast<int32_t>(rng.below(static_cast<uint64_t>(o.num_words)))
                                          : group_word[g]);
    set.sample_frame.push_back(static_cast<frame_t>(s / 100));
    set.sample_keypoint.push_back(-1);
  }

  FeatureMatrix& f = p.features;
  f.num_samples = S;
  f.num_dims = D;
  f.data.assign(static_cast<size_t>(D) * static_cast<size_t>(S), 0);
  // Context noise, column by column with geometric gaps.
  if (o.noise_density > 0.0) {
    const double log_q = std::log1p(-o.noise_density);
    for (int32_t d = 0; d < o.context_dims; ++d) {
      uint8_t* col = f.column(d);
      int64_t s = -1;
      while (true) {
        double u = rng.uniform();
        while (u <= 0.0) u = rng.uniform();
        s += 1 + static_cast<int64_t>(std::floor(std::log(u) / log_q));
        if (s >= S) break;
        col[s] = static_cast<uint8_t>(1 + (rng.next() & 15));
      }
    }
  }
  // Signatures.
  for (int64_t s = 0; s < S; ++s) {
    const int32_t c = set.sample_class[s];
    if (c >= C) continue;
    for (const auto& [d, v] : signature[c]) {
      if (rng.uniform() >= o.signature_keep) continue;
      const int jitter = static_cast<int>(rng.below(33)) - 16;
      f.column(d)[s] = static_cast<uint8_t>(std::clamp(static_cast<int>(v) + jitter, 1, 255));
    }
  }
  // Descriptor bits.
  for (int64_t s = 0; s < S; ++s) {
    const int32_t g = sample_group[s];
    for (int32_t b = 0; b < o.descriptor_bits; ++b) {
      uint8_t bit = g >= 0 ? prototype[g][b] : static_cast<uint8_t>(rng.next() & 1);
      if (g >= 0 && rng.uniform() < o.descriptor_flip) bit ^= 1;
      f.column(o.context_dims + b)[s] = bit;
    }
  }
  set.check();
  return p;
}

}  // namespace lmb
