#include "train/boost/sharing_set.h"

#include <algorithm>
#include <cmath>

namespace lmb {

namespace {

inline double ratio_term(int64_t y, int64_t w) {
  if (w <= 0) return 0.0;
  const double yd = static_cast<double>(y);
  return yd * yd / static_cast<double>(w);
}

struct Sums {
  int64_t wp = 0, yp = 0, wm = 0, ym = 0;
  double q = 0.0;
};

// The fitted point of a set: alpha = Yp/Wp, beta = Ym/Wm (the other value when one side is empty).
inline void fit_point(const Sums& s, double* alpha, double* beta) {
  const bool has_p = s.wp > 0, has_m = s.wm > 0;
  const double a = has_p ? static_cast<double>(s.yp) / static_cast<double>(s.wp) : 0.0;
  const double b = has_m ? static_cast<double>(s.ym) / static_cast<double>(s.wm) : 0.0;
  *alpha = has_p ? a : b;
  *beta = has_m ? b : a;
}

// members[i] = g_i(alpha, beta) > 0; returns the sums of the members.
Sums select(const SharingInput& in, double alpha, double beta, uint8_t* members) {
  Sums s;
  const double a2 = 2.0 * alpha, aa = alpha * alpha, b2 = 2.0 * beta, bb = beta * beta;
  for (int32_t i = 0; i < in.num_classes; ++i) {
    const double g = a2 * static_cast<double>(in.yp[i]) - aa * static_cast<double>(in.wp[i]) +
                     b2 * static_cast<double>(in.ym[i]) - bb * static_cast<double>(in.wm[i]) - in.q[i];
    const bool take = g > 0.0;
    members[i] = take;
    const int64_t mask = -static_cast<int64_t>(take);
    s.wp += in.wp[i] & mask;
    s.yp += in.yp[i] & mask;
    s.wm += in.wm[i] & mask;
    s.ym += in.ym[i] & mask;
    s.q += take ? in.q[i] : 0.0;
  }
  return s;
}

}  // namespace

double sharing_gain(int64_t wp, int64_t yp, int64_t wm, int64_t ym, double sum_q) {
  return ratio_term(yp, wp) + ratio_term(ym, wm) - sum_q;
}

double screen_sharing_gain(const SharingInput& in) {
  const int32_t m = in.num_classes;
  Sums r, f;
  for (int32_t i = 0; i < m; ++i) {
    if (in.wp[i] <= 0 || in.wm[i] <= 0) continue;
    const double lhs = static_cast<double>(in.yp[i]) * static_cast<double>(in.wm[i]);
    const double rhs = static_cast<double>(in.ym[i]) * static_cast<double>(in.wp[i]);
    Sums& s = lhs > rhs ? r : f;
    if (lhs == rhs) continue;
    s.wp += in.wp[i];
    s.yp += in.yp[i];
    s.wm += in.wm[i];
    s.ym += in.ym[i];
    s.q += in.q[i];
  }
  double best = std::max(sharing_gain(r.wp, r.yp, r.wm, r.ym, r.q), sharing_gain(f.wp, f.yp, f.wm, f.ym, f.q));
  double ar, br, af, bf;
  fit_point(r, &ar, &br);
  fit_point(f, &af, &bf);
  const double ar2 = 2.0 * ar, arr = ar * ar, br2 = 2.0 * br, brr = br * br;
  const double af2 = 2.0 * af, aff = af * af, bf2 = 2.0 * bf, bff = bf * bf;
  Sums sr, sf;
  for (int32_t i = 0; i < m; ++i) {
    const double wp = static_cast<double>(in.wp[i]), yp = static_cast<double>(in.yp[i]);
    const double wm = static_cast<double>(in.wm[i]), ym = static_cast<double>(in.ym[i]);
    const double gr = ar2 * yp - arr * wp + br2 * ym - brr * wm - in.q[i];
    const double gf = af2 * yp - aff * wp + bf2 * ym - bff * wm - in.q[i];
    const int64_t mr = -static_cast<int64_t>(gr > 0.0), mf = -static_cast<int64_t>(gf > 0.0);
    sr.wp += in.wp[i] & mr;
    sr.yp += in.yp[i] & mr;
    sr.wm += in.wm[i] & mr;
    sr.ym += in.ym[i] & mr;
    sr.q += gr > 0.0 ? in.q[i] : 0.0;
    sf.wp += in.wp[i] & mf;
    sf.yp += in.yp[i] & mf;
    sf.wm += in.wm[i] & mf;
    sf.ym += in.ym[i] & mf;
    sf.q += gf > 0.0 ? in.q[i] : 0.0;
  }
  best = std::max(best, sharing_gain(sr.wp, sr.yp, sr.wm, sr.ym, sr.q));
  best = std::max(best, sharing_gain(sf.wp, sf.yp, sf.wm, sf.ym, sf.q));
  return best;
}

namespace {
struct SumsD {
  double wp = 0, yp = 0, wm = 0, ym = 0, q = 0;
  double gain() const {
    return (wp > 0 ? yp * yp / wp : 0.0) + (wm > 0 ? ym * ym / wm : 0.0) - q;
  }
  void point(double* alpha, double* beta) const {
    const double a = wp > 0 ? yp / wp : 0.0, b = wm > 0 ? ym / wm : 0.0;
    *alpha = wp > 0 ? a : b;
    *beta = wm > 0 ? b : a;
  }
};
}  // namespace

double screen_sharing_gain(int32_t m, const double* wp, const double* yp, const double* wm, const double* ym,
                           const double* q) {
  SumsD r, f;
  for (int32_t i = 0; i < m; ++i) {
    const double lhs = yp[i] * wm[i], rhs = ym[i] * wp[i];
    // Classes with an empty side have lhs == rhs == 0 and join neither group.
    const bool up = lhs > rhs, down = lhs < rhs;
    r.wp += up ? wp[i] : 0.0;
    r.yp += up ? yp[i] : 0.0;
    r.wm += up ? wm[i] : 0.0;
    r.ym += up ? ym[i] : 0.0;
    r.q += up ? q[i] : 0.0;
    f.wp += down ? wp[i] : 0.0;
    f.yp += down ? yp[i] : 0.0;
    f.wm += down ? wm[i] : 0.0;
    f.ym += down ? ym[i] : 0.0;
    f.q += down ? q[i] : 0.0;
  }
  double best = std::max(r.gain(), f.gain());
  double ar, br, af, bf;
  r.point(&ar, &br);
  f.point(&af, &bf);
  const double ar2 = 2.0 * ar, arr = ar * ar, br2 = 2.0 * br, brr = br * br;
  const double af2 = 2.0 * af, aff = af * af, bf2 = 2.0 * bf, bff = bf * bf;
  SumsD sr, sf;
  for (int32_t i = 0; i < m; ++i) {
    const double gr = ar2 * yp[i] - arr * wp[i] + br2 * ym[i] - brr * wm[i] - q[i];
    const double gf = af2 * yp[i] - aff * wp[i] + bf2 * ym[i] - bff * wm[i] - q[i];
    const bool tr = gr > 0.0, tf = gf > 0.0;
    sr.wp += tr ? wp[i] : 0.0;
    sr.yp += tr ? yp[i] : 0.0;
    sr.wm += tr ? wm[i] : 0.0;
    sr.ym += tr ? ym[i] : 0.0;
    sr.q += tr ? q[i] : 0.0;
    sf.wp += tf ? wp[i] : 0.0;
    sf.yp += tf ? yp[i] : 0.0;
    sf.wm += tf ? wm[i] : 0.0;
    sf.ym += tf ? ym[i] : 0.0;
    sf.q += tf ? q[i] : 0.0;
  }
  return std::max({best, sr.gain(), sf.gain()});
}

SharingResult find_sharing_set(const SharingInput& in, const SharingSearchOptions& options,
                               std::vector<uint8_t>* scratch) {
  SharingResult best;
  const int32_t m = in.num_classes;
  if (m == 0) return best;
  std::vector<uint8_t> local;
  std::vector<uint8_t>& buf = scratch ? *scratch : local;
  buf.assign(3 * static_cast<size_t>(m), 0);
  uint8_t* cur = buf.data();
  uint8_t* prev = cur + m;
  uint8_t* best_set = prev + m;
  bool have_best = false;
  Sums best_sums;

  auto run_from = [&](double alpha, double beta) {
    Sums s;
    double gain = -1.0;
    bool first = true;
    for (int32_t it = 0; it < options.max_iterations; ++it) {
      const Sums next = select(in, alpha, beta, cur);
      const double next_gain = sharing_gain(next.wp, next.yp, next.wm, next.ym, next.q);
      const bool same = !first && std::equal(cur, cur + m, prev);
      if (!first && (same || !(next_gain > gain))) break;
      std::swap(cur, prev);  // prev now holds the accepted set
      s = next;
      gain = next_gain;
      first = false;
      fit_point(s, &alpha, &beta);
    }
    if (!first && gain > 0.0 && (!have_best || gain > best.gain)) {
      have_best = true;
      best.gain = gain;
      best_sums = s;
      std::copy(prev, prev + m, best_set);
    }
  };

  if (options.group_starts) {
    // Rising / falling groups: classes whose own fit has a positive (negative) step.
    for (int dir = 0; dir < 2; ++dir) {
      Sums s;
      for (int32_t i = 0; i < m; ++i) {
        if (in.wp[i] <= 0 || in.wm[i] <= 0) continue;
        // alpha_i > beta_i  <=>  yp_i * wm_i > ym_i * wp_i.
        const double lhs = static_cast<double>(in.yp[i]) * static_cast<double>(in.wm[i]);
        const double rhs = static_cast<double>(in.ym[i]) * static_cast<double>(in.wp[i]);
        if (dir == 0 ? lhs > rhs : lhs < rhs) {
          s.wp += in.wp[i];
          s.yp += in.yp[i];
          s.wm += in.wm[i];
          s.ym += in.ym[i];
        }
      }
      if (s.wp <= 0 && s.wm <= 0) continue;
      double alpha, beta;
      fit_point(s, &alpha, &beta);
      run_from(alpha, beta);
    }
  }
  if (options.single_starts > 0) {
    // Own points of the classes with the largest individual gain g_c = G({c}).
    const int32_t n = std::min(options.single_starts, m);
    std::vector<std::pair<double, int32_t>> top;
    top.reserve(static_cast<size_t>(n) + 1);
    for (int32_t i = 0; i < m; ++i) {
      const double g = sharing_gain(in.wp[i], in.yp[i], in.wm[i], in.ym[i], in.q[i]);
      if (!(g > 0.0)) continue;
      if (static_cast<int32_t>(top.size()) == n && g <= top.back().first) continue;
      auto pos = std::find_if(top.begin(), top.end(), [&](const auto& t) { return g > t.first; });
      top.insert(pos, {g, i});
      if (static_cast<int32_t>(top.size()) > n) top.pop_back();
    }
    for (const auto& [g, i] : top) {
      Sums s{in.wp[i], in.yp[i], in.wm[i], in.ym[i], in.q[i]};
      double alpha, beta;
      fit_point(s, &alpha, &beta);
      run_from(alpha, beta);
    }
  }
  if (have_best) {
    // Polish: best single add/remove with the refit (the greedy step), then re-alternate.
    for (int32_t sweep = 0; sweep < options.max_iterations; ++sweep) {
      int32_t flip = -1;
      double flip_gain = best.gain;
      for (int32_t i = 0; i < m; ++i) {
        const int64_t sg = best_set[i] ? -1 : 1;
        const double g = sharing_gain(best_sums.wp + sg * in.wp[i], best_sums.yp + sg * in.yp[i],
                                      best_sums.wm + sg * in.wm[i], best_sums.ym + sg * in.ym[i],
                                      best_sums.q + static_cast<double>(sg) * in.q[i]);
        if (g > flip_gain * (1.0 + 1e-12)) {
          flip_gain = g;
          flip = i;
        }
      }
      if (flip < 0) break;
      const int64_t sg = best_set[flip] ? -1 : 1;
      best_set[flip] ^= 1;
      best_sums.wp += sg * in.wp[flip];
      best_sums.yp += sg * in.yp[flip];
      best_sums.wm += sg * in.wm[flip];
      best_sums.ym += sg * in.ym[flip];
      // Recompute the q sum in index order (no drift from repeated add/remove).
      best_sums.q = 0.0;
      for (int32_t i = 0; i < m; ++i) best_sums.q += best_set[i] ? in.q[i] : 0.0;
      best.gain = sharing_gain(best_sums.wp, best_sums.yp, best_sums.wm, best_sums.ym, best_sums.q);
      double alpha, beta;
      fit_point(best_sums, &alpha, &beta);
      run_from(alpha, beta);
    }
    best.wp = best_sums.wp;
    best.yp = best_sums.yp;
    best.wm = best_sums.wm;
    best.ym = best_sums.ym;
    for (int32_t i = 0; i < m; ++i) {
      if (best_set[i]) best.members.push_back(i);
    }
  }
  return best;
}

}  // namespace lmb
