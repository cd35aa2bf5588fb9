#include "infer/ransac.h"

#include <climits>

#include "common/error.h"

namespace lmb {

void RansacOptions::check() const {
  LMB_CHECK(max_iterations >= 1, "RansacOptions.max_iterations must be >= 1, got " << max_iterations);
  LMB_CHECK(
      min_iterations >= 0 && min_iterations <= max_iterations,
      "RansacOptions.min_iterations must be in 0..max_iterations (" << max_iterations << "), got " << min_iterations);
  LMB_CHECK(success_probability > 0 && success_probability < 1,
            "RansacOptions.success_probability must be in (0, 1), got " << success_probability);
  LMB_CHECK(
      std::isfinite(prosac_horizon) && (prosac_horizon == 0 || prosac_horizon >= 1),
      "RansacOptions.prosac_horizon must be 0 (= max_iterations) or a finite number >= 1, got " << prosac_horizon);
  LMB_CHECK(random_inlier_probability > 0 && random_inlier_probability < 1,
            "RansacOptions.random_inlier_probability must be in (0, 1), got " << random_inlier_probability);
  LMB_CHECK(non_randomness > 0 && non_randomness < 1,
            "RansacOptions.non_randomness must be in (0, 1), got " << non_randomness);
  LMB_CHECK(min_support >= 0, "RansacOptions.min_support must be >= 0, got " << min_support);
  LMB_CHECK(max_shared_inliers >= 0 && max_shared_inliers < 1,
            "RansacOptions.max_shared_inliers must be in [0, 1), got " << max_shared_inliers);
}

ProsacSampler::ProsacSampler(int num_data, int sample_size, bool progressive, double horizon, uint64_t seed)
    : rng_(seed), num_data_(num_data), sample_size_(sample_size) {
  LMB_CHECK(sample_size >= 1 && num_data >= sample_size,
            "ProsacSampler: " << num_data << " data for samples of " << sample_size);
  left_at_.assign(static_cast<size_t>(num_data) + 1, 0);
  if (!progressive || num_data == sample_size) {
    n_ = num_data;
    return;
  }
  // T_n, the expected number of samples drawn from U_n among horizon samples drawn from U_N
  // (T_m = horizon * C(m, m) / C(N, m), T_{n+1} = T_n (n + 1) / (n + 1 - m)), and PROSAC's integer
  // schedule T'_m = 1, T'_{n+1} = T'_n + ceil(T_{n+1} - T_n).
  const int m = sample_size;
  grow_at_.assign(static_cast<size_t>(num_data) + 1, 0.0);
  double t_n = horizon;
  for (int i = 0; i < m; ++i) t_n *= static_cast<double>(m - i) / (num_data - i);
  double t_prime = 1.0;
  for (int n = m; n < num_data; ++n) {
    grow_at_[n] = t_prime;
    const double t_next = t_n * (n + 1.0) / (n + 1.0 - m);
    t_prime += std::ceil(t_next - t_n);
    t_n = t_next;
  }
  n_ = m;
}

void ProsacSampler::draw_uniform(int count, int range, int* out) {
  for (int k = 0; k < count; ++k) {
    int v = 0;
    bool repeated = true;
    while (repeated) {
      v = static_cast<int>(rng_.below(static_cast<uint64_t>(range)));
      repeated = false;
      for (int j = 0; j < k; ++j) repeated |= out[j] == v;
    }
    out[k] = v;
  }
}

void ProsacSampler::draw(int* sample) {
  ++t_;
  while (n_<num_data_&& static_cast<double>(t_)> grow_at_[n_]) {
    left_at_[n_] = t_ - 1;
    ++n_;
  }
  if (n_ == num_data_) {
    draw_uniform(sample_size_, num_data_, sample);
  } else {
    // The newest datum of U_n and sample_size - 1 of U_{n-1}.
    draw_uniform(sample_size_ - 1, n_ - 1, sample);
    sample[sample_size_ - 1] = n_ - 1;
  }
}

namespace {

// The standard normal quantile of 1 - tail (bisection on erfc; tail in (0, 1)).
double upper_normal_quantile(double tail) {
  double lo = -40.0, hi = 40.0;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(mid / std::sqrt(2.0)) > tail ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

ProsacStopping::ProsacStopping(int num_data, int sample_size, const RansacOptions& options)
    : num_data_(num_data),
      sample_size_(sample_size),
      progressive_(options.progressive),
      log_failure_(std::log1p(-options.success_probability)) {
  const double z = upper_normal_quantile(options.non_randomness);
  const double beta = options.random_inlier_probability;
  min_inliers_.assign(static_cast<size_t>(num_data) + 1, INT_MAX);
  for (int n = sample_size; n <= num_data; ++n) {
    const double others = n - sample_size;
    const double chance = others * beta + z * std::sqrt(others * beta * (1.0 - beta));
    // At least one datum besides the sample, and options.min_support.
    const int above = std::max(1, static_cast<int>(std::ceil(chance)));
    min_inliers_[n] = std::max(sample_size + above, options.min_support);
  }
}

void ProsacStopping::update(const std::vector<char>& inlier_mask) {
  candidates_.clear();
  const int m = sample_size_;
  int inliers = 0;
  std::vector<std::pair<int, double>> all;
  for (int n = 1; n <= num_data_; ++n) {
    inliers += inlier_mask[n - 1] != 0;
    // k_n is smallest where the last datum of U_n is an inlier; U_N always counts (and is the only
    // subset of uniform sampling).
    if (n < num_data_ && (!progressive_ || !inlier_mask[n - 1])) continue;
    if (n < m || inliers < min_inliers_[n]) continue;
    double p = 1.0;
    for (int j = 0; j < m; ++j) p *= static_cast<double>(inliers - j) / (n - j);
    all.emplace_back(n, p >= 1.0 ? 0.0 : log_failure_ / std::log1p(-p));
  }
  // samples_within(n) grows with n, so (n, k) is useless when a larger subset needs no more
  // samples: keep the candidates whose k is below that of every larger subset.
  double below = std::numeric_limits<double>::infinity();
  for (auto it = all.rbegin(); it != all.rend(); ++it) {
    if (it->second < below) {
      candidates_.push_back(*it);
      below = it->second;
    }
  }
  std::reverse(candidates_.begin(), candidates_.end());
}

int ProsacStopping::satisfied(const ProsacSampler& sampler) const {
  for (const auto& [n, k] : candidates_) {
    if (static_cast<double>(sampler.samples_within(n)) >= k) return n;
  }
  return 0;
}

}  // namespace lmb
