#include "train/boost/sharing_set.h"

#include <algorithm>
#include <cmath>

#include "train/boost/screening_gain.h"

namespace lmb {

namespace {

using screening::StepPoint;

struct Sums {
  int64_t wp = 0, yp = 0, wm = 0, ym = 0;
  double q = 0.0;
};

inline void fit_point(const Sums& s, double* alpha, double* beta) {
  screening::fit_point(static_cast<double>(s.wp), static_cast<double>(s.yp), static_cast<double>(s.wm),
                       static_cast<double>(s.ym), alpha, beta);
}

// members[i] = g_i(alpha, beta) > 0; returns the sums of the members.
Sums select(const SharingInput& in, double alpha, double beta, uint8_t* members) {
  Sums s;
  const StepPoint point(alpha, beta);
  for (int32_t i = 0; i < in.num_classes; ++i) {
    const bool take = point.joins(static_cast<double>(in.wp[i]), static_cast<double>(in.yp[i]),
                                  static_cast<double>(in.wm[i]), static_cast<double>(in.ym[i]), in.q[i]);
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
  return screening::set_gain(static_cast<double>(wp), static_cast<double>(yp), static_cast<double>(wm),
                             static_cast<double>(ym), sum_q);
}

double screen_sharing_gain(const SharingInput& in) {
  return screening::screening_gain(
      [&](const auto& add) {
        for (int32_t i = 0; i < in.num_classes; ++i) {
          add(static_cast<double>(in.wp[i]), static_cast<double>(in.yp[i]), static_cast<double>(in.wm[i]),
              static_cast<double>(in.ym[i]), in.q[i]);
        }
      },
      true);
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
        const double wp = static_cast<double>(in.wp[i]), yp = static_cast<double>(in.yp[i]);
        const double wm = static_cast<double>(in.wm[i]), ym = static_cast<double>(in.ym[i]);
        if (dir == 0 ? screening::rising(wp, yp, wm, ym) : screening::falling(wp, yp, wm, ym)) {
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
        const double g =
            sharing_gain(best_sums.wp + sg * in.wp[i], best_sums.yp + sg * in.yp[i], best_sums.wm + sg * in.wm[i],
                         best_sums.ym + sg * in.ym[i], best_sums.q + static_cast<double>(sg) * in.q[i]);
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
