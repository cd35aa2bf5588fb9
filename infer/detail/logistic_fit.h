// Internal (not installed): the penalized logistic regression behind the pose and walk
// calibrations (infer/pose_confidence.h, infer/walk_confidence.h).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Dense>

namespace lmb::detail {

// Fits P(y = 1 | x) = sigma(bias + weights . x) by Newton's method (iteratively reweighted least
// squares) on the log-likelihood with the penalty l2 * m / 2 * |standardized weights|^2 (m
// samples; the bias is free), the features standardized on the samples (a constant feature keeps
// scale 1) and folded back into weights and bias. Stops after max_iterations steps or a step below
// 1e-10. Deterministic: a function of the samples in their order. x and y are non-empty and of one
// size (the callers check).
template <int F>
void fit_logistic(const std::vector<std::array<double, F>>& x, const std::vector<double>& y, double l2,
                  int max_iterations, std::array<double, F>* weights, double* bias) {
  const size_t m = x.size();
  std::array<double, F> mean{}, scale{};
  for (int k = 0; k < F; ++k) {
    double s = 0, s2 = 0;
    for (const auto& f : x) s += f[k];
    mean[k] = s / m;
    for (const auto& f : x) s2 += (f[k] - mean[k]) * (f[k] - mean[k]);
    const double sd = std::sqrt(s2 / m);
    scale[k] = sd > 1e-12 ? sd : 1.0;
  }
  constexpr int D = F + 1;  // weights, then the bias
  Eigen::Matrix<double, D, 1> w = Eigen::Matrix<double, D, 1>::Zero();
  for (int it = 0; it < max_iterations; ++it) {
    Eigen::Matrix<double, D, D> H = Eigen::Matrix<double, D, D>::Zero();
    Eigen::Matrix<double, D, 1> g = Eigen::Matrix<double, D, 1>::Zero();
    for (size_t i = 0; i < m; ++i) {
      Eigen::Matrix<double, D, 1> z;
      for (int k = 0; k < F; ++k) z[k] = (x[i][k] - mean[k]) / scale[k];
      z[F] = 1.0;
      const double p = 1.0 / (1.0 + std::exp(-w.dot(z)));
      g.noalias() += (p - y[i]) * z;
      H.noalias() += std::max(p * (1.0 - p), 1e-12) * z * z.transpose();
    }
    // The penalty scales with the sample count so that its strength does not depend on how many
    // samples were fitted.
    for (int k = 0; k < F; ++k) {
      g[k] += l2 * m * w[k];
      H(k, k) += l2 * m;
    }
    const Eigen::Matrix<double, D, 1> step = H.ldlt().solve(g);
    if (!step.allFinite()) break;
    w -= step;
    if (step.norm() < 1e-10) break;
  }
  *bias = w[F];
  for (int k = 0; k < F; ++k) {
    (*weights)[k] = w[k] / scale[k];
    *bias -= w[k] * mean[k] / scale[k];
  }
}

}  // namespace lmb::detail
