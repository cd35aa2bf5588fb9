#include "common/stats.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numeric>

namespace lmb {

double median(std::vector<double> values, double if_empty) {
  if (values.empty()) return if_empty;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid), values.end());
  const double upper = values[mid];
  if (values.size() % 2 == 1) return upper;
  const double lower = *std::max_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid));
  return 0.5 * (lower + upper);
}

double quantile(std::vector<double> values, double q, double if_empty) {
  if (values.empty()) return if_empty;
  const size_t n = values.size();
  const size_t rank = std::min(n - 1, static_cast<size_t>(std::floor(q * static_cast<double>(n - 1) + 0.5)));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(rank), values.end());
  return values[rank];
}

double mean(const std::vector<double>& values) {
  return values.empty() ? std::numeric_limits<double>::quiet_NaN()
                        : std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
}

}  // namespace lmb
