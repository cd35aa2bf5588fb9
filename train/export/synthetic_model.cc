#include "train/export/synthetic_model.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/random.h"
#include "infer/detail/scoring_index.h"

namespace lmb {

void SyntheticModelOptions::check() const {
  LMB_CHECK(num_classes >= 1, "synthetic model: num_classes = " << num_classes << " must be >= 1");
  LMB_CHECK(num_stumps >= 1, "synthetic model: num_stumps = " << num_stumps << " must be >= 1");
  LMB_CHECK(num_regions >= 1, "synthetic model: num_regions = " << num_regions << " must be >= 1");
  LMB_CHECK(num_words >= 4 && num_words <= 256, "synthetic model: num_words = " << num_words << " outside 4..256");
  LMB_CHECK(descriptor_bytes >= 1 && descriptor_bytes <= kMaxDescriptorBytes,
            "synthetic model: descriptor_bytes = " << descriptor_bytes << " outside 1.." << kMaxDescriptorBytes);
  LMB_CHECK(context_stump_share >= 0.0 && context_stump_share <= 1.0,
            "synthetic model: context_stump_share = " << context_stump_share << " outside [0, 1]");
  LMB_CHECK(sharing_m0 > 0.0 && std::isfinite(sharing_m0),
            "synthetic model: sharing_m0 = " << sharing_m0 << " must be > 0");
  LMB_CHECK(sharing_decay >= 0.0 && std::isfinite(sharing_decay),
            "synthetic model: sharing_decay = " << sharing_decay << " must be >= 0");
  LMB_CHECK(background_share >= 0.0 && background_share <= 1.0,
            "synthetic model: background_share = " << background_share << " outside [0, 1]");
  LMB_CHECK(extra_word_probability >= 0.0 && extra_word_probability <= 1.0,
            "synthetic model: extra_word_probability = " << extra_word_probability << " outside [0, 1]");
}

ModelData make_synthetic_model(const SyntheticModelOptions& o, SyntheticModelStats* stats) {
  o.check();
  Rng rng(o.seed);
  ModelData d;
  d.detector = "SYNTHETIC";
  d.descriptor_bytes = o.descriptor_bytes;
  ContextRegionOptions ro;
  ro.num_regions = o.num_regions;
  ro.seed = o.seed;
  d.regions = ContextRegions(ro);
  std::vector<uint8_t> words(static_cast<size_t>(o.num_words) * o.descriptor_bytes);
  for (uint8_t& b : words) b = static_cast<uint8_t>(rng.below(256));
  d.vocabulary = Vocabulary(o.descriptor_bytes, std::move(words));

  const int32_t C = o.num_classes;
  d.num_classes = C;
  for (int32_t c = 0; c < C; ++c) {
    d.class_landmark.push_back(c);
    d.class_position.emplace_back(rng.uniform(0.0, 100.0), rng.uniform(0.0, 20.0), rng.uniform(0.0, 5.0));
  }
  for (int32_t c = 0; c <= C; ++c) d.bias.push_back(rng.normal());

  const EmbeddingLayout layout = detail::layout_of(d);
  std::vector<int32_t> all(static_cast<size_t>(C));
  for (int32_t c = 0; c < C; ++c) all[c] = c;
  SyntheticModelStats st;
  for (int32_t m = 0; m < o.num_stumps; ++m) {
    SharedStump s;
    if (rng.uniform() < o.context_stump_share) {
      s.dim = static_cast<int32_t>(rng.below(static_cast<uint64_t>(layout.num_context_dims())));
      s.theta = static_cast<uint8_t>(rng.below(64));
    } else {
      s.dim =
          layout.num_context_dims() + static_cast<int32_t>(rng.below(static_cast<uint64_t>(8 * o.descriptor_bytes)));
      s.theta = 0;
    }
    s.a = rng.normal();
    s.b = 0.5 * rng.normal();
    const double mean = 0.5 * C * std::pow(1.0 + m / o.sharing_m0, -o.sharing_decay);
    const int32_t size =
        static_cast<int32_t>(std::clamp(std::lround(mean * std::exp(0.5 * rng.normal())), 1L, static_cast<long>(C)));
    // A random subset of `size` classes: a partial Fisher-Yates shuffle.
    for (int32_t i = 0; i < size; ++i) {
      std::swap(all[i], all[i + static_cast<int32_t>(rng.below(static_cast<uint64_t>(C - i)))]);
    }
    s.classes.assign(all.begin(), all.begin() + size);
    std::sort(s.classes.begin(), s.classes.end());
    if (rng.uniform() < o.background_share) s.classes.push_back(C);
    st.sharing_entries += static_cast<int64_t>(s.classes.size());
    d.stumps.push_back(std::move(s));
  }

  d.inverted_file.resize(static_cast<size_t>(o.num_words));
  for (int32_t c = 0; c < C; ++c) {
    const int32_t first = static_cast<int32_t>(rng.below(static_cast<uint64_t>(o.num_words)));
    for (int32_t w = 0; w < o.num_words; ++w) {
      if (w == first || rng.uniform() < o.extra_word_probability) {
        d.inverted_file[w].push_back(c);
        ++st.inverted_file_entries;
      }
    }
  }
  d.check("synthetic model");
  if (stats) *stats = st;
  return d;
}

}  // namespace lmb
