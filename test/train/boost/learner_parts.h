// Test helper of the learner's parts: a synthetic problem's feature columns and bootstrapped
// entries after one random update (unequal weights), quantized; and brute-force sums over them.
#pragma once

#include <memory>
#include <vector>

#include "common/random.h"
#include "train/boost/boost_options.h"
#include "train/boost/entry_store.h"
#include "train/boost/feature_columns.h"
#include "train/boost/negative_miner.h"
#include "train/boost/synthetic_problem.h"

namespace lmb::test {

struct Parts {
  SyntheticBoostProblem problem;
  BoostOptions options;
  std::unique_ptr<FeatureColumns> columns;
  std::unique_ptr<EntryStore> entries;
};

inline std::unique_ptr<Parts> make_parts(int32_t max_thresholds, bool blocked = true) {
  auto p = std::make_unique<Parts>();
  SyntheticBoostOptions so;
  so.num_classes = 40;
  so.noise_density = 0.4;
  p->problem = make_synthetic_boost_problem(so);
  p->options.screening.max_thresholds = max_thresholds;
  p->options.screening.blocked = blocked;
  const TrainingSet& set = p->problem.set;
  const int32_t C1 = set.num_classes_with_background();
  p->columns = std::make_unique<FeatureColumns>(p->problem.features, p->options.screening);
  p->entries = std::make_unique<EntryStore>(set.num_samples(), C1);
  NegativeMiner(set, p->options).bootstrap(p->entries.get());
  Rng rng(17);
  std::vector<uint8_t> above(static_cast<size_t>(set.num_samples())), in_set(static_cast<size_t>(C1));
  for (auto& a : above) a = rng.uniform() < 0.4;
  for (auto& s : in_set) s = rng.uniform() < 0.5;
  std::vector<double> k(static_cast<size_t>(C1));
  for (double& x : k) x = rng.uniform(-0.5, 0.5);
  p->entries->quantize(0);
  p->entries->update(above, in_set, 0.7, -0.3, k);
  p->entries->quantize(1);
  return p;
}

// Per class: positive and negative fixed-point weight above theta, from the entries one by one.
inline void brute_force_above(const Parts& p, int32_t dim, int theta, std::vector<int64_t>* pos,
                              std::vector<int64_t>* neg) {
  const EntryStore& e = *p.entries;
  pos->assign(static_cast<size_t>(e.num_classes()), 0);
  neg->assign(static_cast<size_t>(e.num_classes()), 0);
  const uint8_t* col = p.columns->get(dim, "test").column;
  for (int64_t s = 0; s < e.num_samples(); ++s) {
    if (col[s] <= theta) continue;
    for (int64_t i = e.sample_begin()[s]; i < e.sample_begin()[s + 1]; ++i) {
      ((e.code(i) & 1) ? *neg : *pos)[e.code(i) >> 1] += e.hot()[i].wq;
    }
  }
}

}  // namespace lmb::test
