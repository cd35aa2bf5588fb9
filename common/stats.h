// Order statistics of a sample: the median, quantiles and the mean, one definition for every report.
#pragma once

#include <limits>
#include <vector>

namespace lmb {

// The median: the middle value, or the mean of the two middle values of an even count; `if_empty`
// for no value.
double median(std::vector<double> values, double if_empty = std::numeric_limits<double>::quiet_NaN());

// The q-quantile (q in [0, 1]) by the nearest rank: the value at rank round(q * (n - 1)) of the
// sorted sample; `if_empty` for no value.
double quantile(std::vector<double> values, double q, double if_empty = std::numeric_limits<double>::quiet_NaN());

// The arithmetic mean; NaN for no value.
double mean(const std::vector<double>& values);

}  // namespace lmb
