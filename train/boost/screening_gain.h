// The screening-gain kernel: the one definition of how a set of classes sharing a stump is fitted
// and scored, and of the cheap screening that ranks (dim, threshold) candidates before the full
// sharing-set search. Every caller uses it: the column screening and the blocked class-major
// screening of train/boost/column_screener.h (the latter on four thresholds at a time in SIMD
// lanes), screen_sharing_gain and find_sharing_set (train/boost/sharing_set.h), and the round's fit.
//
// Per class c of a candidate (dim, theta), in fixed-point weight units: the sums above the
// threshold wp = sum w, yp = sum w z, below it wm, ym, and q = (yp + ym)^2 / (wp + wm). A set S
// with sums Wp, Yp, Wm, Ym, Q gains
//   G(S) = Yp^2 / Wp + Ym^2 / Wm - Q          (a side without weight adds 0)
// at its fitted point alpha = Yp / Wp, beta = Ym / Wm (a side without weight takes the other
// side's value). Screening scores a threshold by the better of two groups: the "rising" classes,
// whose own fit steps up (alpha_c > beta_c, i.e. yp wm > ym wp) and the "falling" ones (<); a
// class with an empty side has yp wm = ym wp = 0 and joins neither. With a step, also the sets
// {c : g_c(alpha, beta) > 0} at each group's point, where
//   g_c(alpha, beta) = 2 alpha yp - alpha^2 wp + 2 beta ym - beta^2 wm - q.
//
// Bit-identity: the sums are of integers below 2^52 (EntryStore::quantize), so adding them in
// doubles is exact in any order and grouping; q sums in ascending class order in every caller,
// and a class that joins no group adds +0.0, which changes no sum (sums are never -0.0). So the
// scalar and SIMD screenings, the serial and distributed learners give the same gains bit for bit.
#pragma once

#include <algorithm>
#include <cstdint>

namespace lmb::screening {

#define LMB_KERNEL inline __attribute__((always_inline))

// G(S) of a set's sums.
LMB_KERNEL double set_gain(double wp, double yp, double wm, double ym, double q) {
  return (wp > 0 ? yp * yp / wp : 0.0) + (wm > 0 ? ym * ym / wm : 0.0) - q;
}

// The fitted (alpha, beta) of a set's sums.
LMB_KERNEL void fit_point(double wp, double yp, double wm, double ym, double* alpha, double* beta) {
  const double a = wp > 0 ? yp / wp : 0.0, b = wm > 0 ? ym / wm : 0.0;
  *alpha = wp > 0 ? a : b;
  *beta = wm > 0 ? b : a;
}

// g_c(alpha, beta) > 0: the classes that gain at a point.
struct StepPoint {
  double a2, aa, b2, bb;
  StepPoint(double alpha, double beta) : a2(2.0 * alpha), aa(alpha * alpha), b2(2.0 * beta), bb(beta * beta) {}
  LMB_KERNEL bool joins(double wp, double yp, double wm, double ym, double q) const {
    return a2 * yp - aa * wp + b2 * ym - bb * wm - q > 0.0;
  }
};

// A class's own step direction, in the group starts of the sharing-set search.
LMB_KERNEL bool rising(double wp, double yp, double wm, double ym) { return yp * wm > ym * wp; }
LMB_KERNEL bool falling(double wp, double yp, double wm, double ym) { return yp * wm < ym * wp; }

// Four doubles and their comparison masks (GCC vector extensions), for four thresholds at a time.
using V4d = double __attribute__((vector_size(32)));
using V4l = int64_t __attribute__((vector_size(32)));

// sums[f] += fields[f] where `take` (one class, scalar, or four thresholds, per lane).
LMB_KERNEL void add_where(bool take, double (&sums)[5], const double (&fields)[5]) {
  if (take) {
    for (int f = 0; f < 5; ++f) sums[f] += fields[f];
  }
}
LMB_KERNEL void add_where(const V4l& take, V4d (&sums)[5], const V4d (&fields)[5]) {
  const V4d zero = {0, 0, 0, 0};
  for (int f = 0; f < 5; ++f) sums[f] += take ? fields[f] : zero;
}

// The rising and falling groups' sums (wp, yp, wm, ym, q) of one threshold (V = double) or four
// (V = V4d), one class added at a time, in class order.
template <class V>
struct Groups {
  V rise[5] = {}, fall[5] = {};
  LMB_KERNEL void add(const V& wp, const V& yp, const V& wm, const V& ym, const V& q) {
    const V fields[5] = {wp, yp, wm, ym, q};
    add_where(yp * wm > ym * wp, rise, fields);
    add_where(yp * wm < ym * wp, fall, fields);
  }
};

LMB_KERNEL double gain_of(const double (&s)[5]) { return set_gain(s[0], s[1], s[2], s[3], s[4]); }
LMB_KERNEL StepPoint point_of(const double (&s)[5]) {
  double alpha, beta;
  fit_point(s[0], s[1], s[2], s[3], &alpha, &beta);
  return StepPoint(alpha, beta);
}

// The screening gain of one threshold. for_each_class(f) calls f(wp, yp, wm, ym, q) for the
// classes of the threshold in ascending class order (it may leave out classes without weight on
// either side: they join no group and no step set); it runs twice with `step`.
template <class ForEachClass>
double screening_gain(const ForEachClass& for_each_class, bool step) {
  Groups<double> g;
  for_each_class([&](double wp, double yp, double wm, double ym, double q) { g.add(wp, yp, wm, ym, q); });
  double best = std::max(gain_of(g.rise), gain_of(g.fall));
  if (!step) return best;
  const StepPoint from_rise = point_of(g.rise), from_fall = point_of(g.fall);
  double s_rise[5] = {}, s_fall[5] = {};
  for_each_class([&](double wp, double yp, double wm, double ym, double q) {
    const double fields[5] = {wp, yp, wm, ym, q};
    add_where(from_rise.joins(wp, yp, wm, ym, q), s_rise, fields);
    add_where(from_fall.joins(wp, yp, wm, ym, q), s_fall, fields);
  });
  return std::max({best, gain_of(s_rise), gain_of(s_fall)});
}

#undef LMB_KERNEL

}  // namespace lmb::screening
