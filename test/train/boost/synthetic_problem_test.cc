#include "train/boost/synthetic_problem.h"

#include <gtest/gtest.h>

namespace lmb {
namespace {

TEST(SyntheticProblem, HasTheRequestedShapeAndAliasing) {
  SyntheticBoostOptions o;
  const SyntheticBoostProblem p = make_synthetic_boost_problem(o);
  EXPECT_EQ(p.set.num_classes, o.num_classes);
  EXPECT_EQ(p.set.num_samples(), int64_t{o.num_classes} * o.observations_per_class + o.num_background);
  EXPECT_EQ(p.features.num_dims, o.context_dims + o.descriptor_bits);
  EXPECT_EQ(p.features.data.size(), static_cast<size_t>(p.features.num_dims) * p.features.num_samples);
  // Descriptor bits are binary; context bins are mostly zero.
  int64_t nonzero = 0;
  for (int32_t d = 0; d < o.context_dims; ++d) {
    for (int64_t s = 0; s < p.features.num_samples; ++s) nonzero += p.features.column(d)[s] != 0;
  }
  const double density = static_cast<double>(nonzero) / (double(o.context_dims) * p.features.num_samples);
  EXPECT_GT(density, 0.5 * o.noise_density);
  EXPECT_LT(density, 0.2);
  for (int32_t b = 0; b < o.descriptor_bits; ++b) {
    for (int64_t s = 0; s < p.features.num_samples; ++s) EXPECT_LE(p.features.column(o.context_dims + b)[s], 1);
  }
  // Same seed, same data.
  EXPECT_EQ(make_synthetic_boost_problem(o).features.data, p.features.data);
}

}  // namespace
}  // namespace lmb
