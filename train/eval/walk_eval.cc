#include "train/eval/walk_eval.h"

#include <algorithm>
#include <cstdio>
#include <optional>

#include "common/error.h"
#include "common/stats.h"

namespace lmb {

namespace {

struct WalkFigures {
  int64_t frames = 0, right = 0, reported = 0, reported_right = 0;
  int64_t disagreeing = 0;  // poses refused because they disagree with the frame before
  int64_t outside_frames = 0, outside_reported = 0, outside_reported_after_2 = 0;
  int64_t first_reported = -1;  // index of the first reported frame, -1: none
  double ms_to_first = -1.0;    // time of the frames up to and including it
  std::vector<double> ms;       // per frame of the walk (outside frames excluded)

  void add(const WalkFigures& o) {
    frames += o.frames;
    right += o.right;
    reported += o.reported;
    reported_right += o.reported_right;
    disagreeing += o.disagreeing;
    outside_frames += o.outside_frames;
    outside_reported += o.outside_reported;
    outside_reported_after_2 += o.outside_reported_after_2;
    ms.insert(ms.end(), o.ms.begin(), o.ms.end());
  }

  nlohmann::json to_json(bool with_first) const {
    const double n = static_cast<double>(frames);
    nlohmann::json j = {{"frames", frames},
                        {"frames_right", right},
                        {"reported", reported},
                        {"reported_right", reported_right},
                        {"disagreeing", disagreeing},
                        {"precision", reported > 0 ? static_cast<double>(reported_right) / reported : 1.0},
                        {"recall", frames > 0 ? static_cast<double>(reported_right) / n : 0.0},
                        {"mean_ms", mean(ms)},
                        {"p95_ms", quantile(ms, 0.95)}};
    if (with_first) {
      j["first_reported_frame"] = first_reported;
      j["ms_to_first_reported"] = ms_to_first;
    }
    j["outside_frames"] = outside_frames;
    j["outside_reported"] = outside_reported;
    j["outside_reported_after_2"] = outside_reported_after_2;
    return j;
  }
};

// One walk judged by `tracker`: the walk's frames, then (a walk leaving the map) the outside frames.
WalkFigures run_walk(WalkTracker tracker, const std::vector<FrameOutcome>& frames,
                     const std::vector<FrameOutcome>* outside, const PoseThresholds& thresholds) {
  WalkFigures w;
  double elapsed = 0.0;
  for (const FrameOutcome& f : frames) {
    const WalkVerdict v = tracker.update(f.localized, f.cam_from_world, f.evidence);
    const bool right = f.localized && pose_within(f.cam_from_world, f.true_cam_from_world, thresholds);
    elapsed += f.total_ms;
    w.ms.push_back(f.total_ms);
    w.right += right;
    w.reported += v.localized;
    w.reported_right += v.localized && right;
    w.disagreeing += v.agreement_applies && !v.agrees;
    if (v.localized && w.first_reported < 0) {
      w.first_reported = w.frames;
      w.ms_to_first = elapsed;
    }
    ++w.frames;
  }
  if (outside != nullptr) {
    for (size_t i = 0; i < outside->size(); ++i) {
      const FrameOutcome& f = (*outside)[i];
      const WalkVerdict v = tracker.update(f.localized, f.cam_from_world, f.evidence);
      ++w.outside_frames;
      w.outside_reported += v.localized;
      w.outside_reported_after_2 += v.localized && i >= 2;
    }
  }
  return w;
}

// mean [min, max] of field over the seeds' totals.
nlohmann::json seed_range(const nlohmann::json& totals, const char* rule, const char* field) {
  double sum = 0, lo = 1e300, hi = -1e300;
  for (const nlohmann::json& t : totals) {
    const double v = t.at(rule).at(field).get<double>();
    sum += v;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  const double n = static_cast<double>(totals.size());
  return {{"mean", totals.empty() ? 0.0 : sum / n}, {"min", lo}, {"max", hi}};
}

}  // namespace

nlohmann::json evaluate_walks(const std::vector<WalkInput>& walks,
                              const std::vector<std::vector<FrameOutcome>>& outside_by_seed,
                              const CalibrationFit& frame_fit, const WalkCalibrationFit& walk_fit,
                              const std::vector<uint64_t>& seeds, const PoseThresholds& thresholds) {
  LMB_CHECK(frame_fit.fitted, "walks: the method's pose calibration is not fitted");
  for (const WalkInput& w : walks) {
    LMB_CHECK(w.by_seed.size() == seeds.size(),
              "walks: " << w.name << " has " << w.by_seed.size() << " seeds, expected " << seeds.size());
  }
  LMB_CHECK(outside_by_seed.empty() || outside_by_seed.size() == seeds.size(),
            "walks: outside frames of " << outside_by_seed.size() << " seeds, expected " << seeds.size());
  const std::optional<WalkCalibration> walk =
      walk_fit.fitted ? std::optional<WalkCalibration>(walk_fit.calibration) : std::nullopt;
  nlohmann::json per_walk = nlohmann::json::array();
  nlohmann::json totals = nlohmann::json::array();
  std::vector<WalkFigures> walk_total(seeds.size()), frame_total(seeds.size());
  for (const WalkInput& w : walks) {
    nlohmann::json by_seed = nlohmann::json::array();
    for (size_t s = 0; s < seeds.size(); ++s) {
      const std::vector<FrameOutcome>* outside = outside_by_seed.empty() ? nullptr : &outside_by_seed[s];
      const WalkFigures a = run_walk(WalkTracker(frame_fit.calibration, walk), w.by_seed[s], outside, thresholds);
      const WalkFigures b =
          run_walk(WalkTracker(frame_fit.calibration, std::nullopt), w.by_seed[s], outside, thresholds);
      walk_total[s].add(a);
      frame_total[s].add(b);
      by_seed.push_back({{"seed", seeds[s]}, {"walk_rule", a.to_json(true)}, {"frame_rule", b.to_json(true)}});
    }
    per_walk.push_back({{"session", w.name}, {"seeds", by_seed}});
  }
  for (size_t s = 0; s < seeds.size(); ++s) {
    totals.push_back({{"seed", seeds[s]},
                      {"walk_rule", walk_total[s].to_json(false)},
                      {"frame_rule", frame_total[s].to_json(false)}});
  }
  return {{"calibration", walk_fit.to_json()}, {"seeds", seeds}, {"walks", per_walk}, {"total", totals}};
}

nlohmann::json walk_summary(const nlohmann::json& walk) {
  const nlohmann::json& totals = walk.at("total");
  nlohmann::json summary = nlohmann::json::object();
  for (const char* rule : {"walk_rule", "frame_rule"}) {
    for (const char* field : {"reported", "reported_right", "precision", "recall", "mean_ms", "p95_ms"}) {
      summary[rule][field] = seed_range(totals, rule, field);
    }
    for (const char* field : {"outside_frames", "outside_reported", "outside_reported_after_2"}) {
      summary[rule][field] = seed_range(totals, rule, field);
    }
  }
  return summary;
}

std::string format_walk_table(const nlohmann::json& report) {
  const auto methods = report.find("methods");
  if (methods == report.end() || !methods->is_object()) return "";
  std::string out;
  char cell[512];
  for (const auto& [name, m] : methods->items()) {
    const auto c = m.find("pose_confidence");
    if (c == m.end() || !c->contains("walk")) continue;
    const nlohmann::json& w = c->at("walk");
    if (out.empty()) {
      out +=
          "\nwalks (each query session tracked frame after frame; mean [min, max] over RANSAC seeds): frames "
          "reported right and precision, by the frame rule alone and by the walk rule:\n";
      std::snprintf(cell, sizeof(cell), "%-24s %7s %26s %22s %26s %22s %9s  %s\n", "method", "frames",
                    "frame rule: reported right", "precision", "walk rule: reported right", "precision", "mean ms",
                    "outside frames reported (walk rule)");
      out += cell;
    }
    const nlohmann::json s = walk_summary(w);
    const auto range = [&](const char* rule, const char* field, const char* fmt) {
      const nlohmann::json& r = s.at(rule).at(field);
      char t[96];
      std::snprintf(t, sizeof(t), fmt, r.at("mean").get<double>(), r.at("min").get<double>(),
                    r.at("max").get<double>());
      return std::string(t);
    };
    const nlohmann::json& total = w.at("total");
    const long long frames = total.empty() ? 0 : total.front().at("walk_rule").at("frames").get<long long>();
    std::snprintf(cell, sizeof(cell), "%-24s %7lld %26s %22s %26s %22s %9.2f  %s\n", name.c_str(), frames,
                  range("frame_rule", "reported_right", "%.1f [%.0f, %.0f]").c_str(),
                  range("frame_rule", "precision", "%.3f [%.3f, %.3f]").c_str(),
                  range("walk_rule", "reported_right", "%.1f [%.0f, %.0f]").c_str(),
                  range("walk_rule", "precision", "%.3f [%.3f, %.3f]").c_str(),
                  s.at("walk_rule").at("mean_ms").at("mean").get<double>(),
                  s.at("walk_rule").at("outside_frames").at("max").get<double>() > 0
                      ? range("walk_rule", "outside_reported", "%.1f [%.0f, %.0f]").c_str()
                      : "-");
    out += cell;
  }
  return out;
}

}  // namespace lmb
