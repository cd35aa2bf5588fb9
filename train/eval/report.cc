#include "train/eval/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <string>

#include "common/error.h"
#include "common/file_container.h"

namespace lmb {

namespace {

nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json numbers(const std::vector<double>& v) {
  nlohmann::json a = nlohmann::json::array();
  for (double x : v) a.push_back(number(x));
  return a;
}

nlohmann::json sweep_report(const PoseSweep& sweep) {
  nlohmann::json recall = nlohmann::json::array(), mean = nlohmann::json::array();
  nlohmann::json lo = nlohmann::json::array(), hi = nlohmann::json::array();
  for (size_t b = 0; b < sweep.iterations.size(); ++b) {
    nlohmann::json row = nlohmann::json::array();
    for (size_t s = 0; s < sweep.seeds.size(); ++s) row.push_back(number(sweep.recall(b, s)));
    recall.push_back(row);
    const SeedRange range = seed_range(sweep, b);
    mean.push_back(number(range.mean));
    lo.push_back(number(range.min));
    hi.push_back(number(range.max));
  }
  return {{"ransac_iterations", sweep.iterations},
          {"seeds", sweep.seeds},
          {"recall", recall},
          {"mean", mean},
          {"min", lo},
          {"max", hi}};
}

double scalar(const nlohmann::json& m, const char* key) {
  const auto it = m.find(key);
  if (it == m.end() || !it->is_number()) return std::nan("");
  return it->get<double>();
}

}  // namespace

nlohmann::json json_number_or_string(double value) {
  if (std::isfinite(value)) return value;
  if (std::isnan(value)) return "nan";
  return value > 0 ? "inf" : "-inf";
}

nlohmann::json method_report(const MethodResult& r) {
  const RetrievalMetrics& q = r.retrieval;
  const PoseMetrics& p = r.pose;
  nlohmann::json m;
  m["precision_at_1"] = number(q.precision_at_1);
  m["mrr"] = number(q.mrr);
  m["miss_rate_at_fppi"] = {{"0.1", number(q.miss_rate_at_fppi_0_1)},
                            {"1", number(q.miss_rate_at_fppi_1)},
                            {"10", number(q.miss_rate_at_fppi_10)}};
  m["match_precision"] = number(r.matches.match_precision);
  m["match_recall"] = number(r.matches.match_recall);
  m["accepted_matches_per_frame"] =
      number(p.num_frames > 0 ? static_cast<double>(r.matches.num_accepted) / static_cast<double>(p.num_frames) : 0.0);
  m["pose_recall_20cm_5deg"] = number(p.recall_20cm_5deg);
  m["pose_auc"] = number(p.auc);
  m["median_position_error_m"] = number(p.median_position_error_m);
  m["median_rotation_error_deg"] = number(p.median_rotation_error_deg);
  // The 7-Scenes convention: 5 cm / 5 deg, and medians over all frames, which may be infinite
  // ("inf"); null without frames.
  m["pose_recall_5cm_5deg"] = number(p.recall_5cm_5deg);
  const auto all_frames = [&](double v) { return p.num_frames > 0 ? json_number_or_string(v) : nlohmann::json(); };
  m["median_position_error_all_frames_m"] = all_frames(p.median_position_error_all_frames_m);
  m["median_rotation_error_all_frames_deg"] = all_frames(p.median_rotation_error_all_frames_deg);
  m["mean_inlier_ratio"] = number(p.mean_inlier_ratio);
  m["match_ms_per_frame"] = number(p.mean_match_ms);
  m["total_ms_per_frame"] = number(p.mean_total_ms);
  m["log_average_miss_rate"] = number(q.log_average_miss_rate);
  m["background_rejection_rate"] = number(r.matches.background_rejection_rate);
  m["frames_localized"] = p.num_localized;
  m["frames_correct"] = p.num_correct;

  nlohmann::json mr = {
      {"n", nlohmann::json::array()}, {"fppi", nlohmann::json::array()}, {"miss_rate", nlohmann::json::array()}};
  for (const MissRatePoint& pt : q.miss_rate_curve) {
    mr["n"].push_back(pt.n);
    mr["fppi"].push_back(number(pt.fppi));
    mr["miss_rate"].push_back(number(pt.miss_rate));
  }
  m["miss_rate_curve"] = mr;
  nlohmann::json pr = {{"threshold", nlohmann::json::array()},
                       {"recall", nlohmann::json::array()},
                       {"precision", nlohmann::json::array()}};
  for (const PosePrPoint& pt : p.pr_curve) {
    pr["threshold"].push_back(number(pt.threshold));
    pr["recall"].push_back(number(pt.recall));
    pr["precision"].push_back(number(pt.precision));
  }
  m["pose_pr_curve"] = pr;
  if (!r.recall_at_thresholds.empty()) {
    nlohmann::json at = nlohmann::json::array();
    for (const ThresholdRecall& t : r.recall_at_thresholds) {
      at.push_back({{"max_position_error_m", t.thresholds.max_position_error_m},
                    {"max_rotation_error_deg", t.thresholds.max_rotation_error_deg},
                    {"frames_correct", t.frames_correct},
                    {"recall", number(t.recall)}});
    }
    m["pose_recall_at_thresholds"] = at;
  }
  if (!r.sweep.iterations.empty()) m["pose_recall_sweep"] = sweep_report(r.sweep);

  nlohmann::json f;
  nlohmann::json localized = nlohmann::json::array(), correct = nlohmann::json::array();
  for (size_t i = 0; i < p.correct.size(); ++i) {
    localized.push_back(std::isfinite(p.position_error_m[i]) ? 1 : 0);
    correct.push_back(p.correct[i] ? 1 : 0);
  }
  f["localized"] = localized;
  f["correct"] = correct;
  f["position_error_m"] = numbers(p.position_error_m);
  f["rotation_error_deg"] = numbers(p.rotation_error_deg);
  f["inlier_ratio"] = numbers(p.inlier_ratio);
  if (!r.frames.empty()) {
    std::vector<double> match, total;
    for (const FrameOutcome& o : r.frames) {
      match.push_back(o.match_ms);
      total.push_back(o.total_ms);
    }
    f["match_ms"] = numbers(match);
    f["total_ms"] = numbers(total);
  }
  m["per_frame"] = f;
  return m;
}

nlohmann::json build_report(const DatasetCounts& dataset, const std::vector<MethodResult>& methods) {
  nlohmann::json report;
  report["dataset"] = {{"map_frames", dataset.map_frames},
                       {"query_frames", dataset.query_frames},
                       {"landmarks", dataset.landmarks},
                       {"query_keypoints", dataset.query_keypoints},
                       {"query_keypoints_with_truth", dataset.query_keypoints_with_truth}};
  report["methods"] = nlohmann::json::object();
  std::set<std::string> seen;
  for (const MethodResult& r : methods) {
    LMB_CHECK(!r.name.empty(), "build_report: a method has an empty name");
    LMB_CHECK(seen.insert(r.name).second, "build_report: method '" << r.name << "' appears twice");
    LMB_CHECK(r.frames.empty() || static_cast<int64_t>(r.frames.size()) == r.pose.num_frames,
              "build_report: method '" << r.name << "' has " << r.frames.size() << " frame outcomes but "
                                       << r.pose.num_frames << " evaluated frames");
    report["methods"][r.name] = method_report(r);
  }
  return report;
}

nlohmann::json session_method_report(const MethodResult& r) {
  nlohmann::json m = {{"precision_at_1", number(r.retrieval.precision_at_1)},
                      {"mrr", number(r.retrieval.mrr)},
                      {"pose_recall_20cm_5deg", number(r.pose.recall_20cm_5deg)},
                      {"frames_localized", r.pose.num_localized},
                      {"frames_correct", r.pose.num_correct}};
  if (!r.sweep.iterations.empty()) {
    nlohmann::json sweep = sweep_report(r.sweep);
    sweep.erase("recall");
    sweep.erase("seeds");
    m["pose_recall_sweep"] = sweep;
  }
  return m;
}

nlohmann::json generalization_gap(const nlohmann::json& report) {
  nlohmann::json p1 = nlohmann::json::object(), pose = nlohmann::json::object();
  const auto held = report.find("held_out_map_observations");
  const auto sessions = report.find("sessions");
  const auto methods = report.find("methods");
  if (methods == report.end() || !methods->is_object()) {
    return {{"precision_at_1", p1}, {"pose_recall_20cm_5deg", pose}};
  }
  for (const auto& [name, m] : methods->items()) {
    nlohmann::json row = {{"held_out_map_observations", nullptr}, {"sessions", nlohmann::json::object()}};
    nlohmann::json pose_row = nlohmann::json::object();
    if (held != report.end() && held->contains("methods") && held->at("methods").contains(name)) {
      row["held_out_map_observations"] = held->at("methods").at(name).at("precision_at_1");
    }
    if (sessions != report.end() && sessions->is_array()) {
      for (const nlohmann::json& s : *sessions) {
        const auto sm = s.at("methods").find(name);
        if (sm == s.at("methods").end()) continue;
        row["sessions"][s.at("name").get<std::string>()] = sm->at("precision_at_1");
        pose_row[s.at("name").get<std::string>()] = sm->at("pose_recall_20cm_5deg");
      }
    }
    p1[name] = row;
    pose[name] = pose_row;
  }
  return {{"precision_at_1", p1}, {"pose_recall_20cm_5deg", pose}};
}

void write_report(const std::filesystem::path& path, const nlohmann::json& report) {
  const std::string text = report.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
  write_file_atomically(path, text.data(), text.size());
}

namespace {

// The pose recall over the seeds at each budget, one row per method.
std::string format_sweep_table(const nlohmann::json& methods) {
  std::string out;
  const nlohmann::json* first = nullptr;
  for (const auto& [name, m] : methods.items()) {
    if (m.contains("pose_recall_sweep")) {
      first = &m.at("pose_recall_sweep");
      break;
    }
  }
  if (first == nullptr) return out;
  const nlohmann::json& seeds = first->at("seeds");
  char line[512];
  std::snprintf(line, sizeof(line), "\npose recall over %zu RANSAC seeds (%llu..%llu), mean [min, max]:\n%-24s",
                seeds.size(), seeds.front().get<unsigned long long>(), seeds.back().get<unsigned long long>(),
                "method");
  out += line;
  for (const auto& it : first->at("ransac_iterations")) {
    std::snprintf(line, sizeof(line), " %21s", (std::to_string(it.get<int>()) + " iterations").c_str());
    out += line;
  }
  out += "\n";
  for (const auto& [name, m] : methods.items()) {
    const auto sw = m.find("pose_recall_sweep");
    if (sw == m.end()) continue;
    std::snprintf(line, sizeof(line), "%-24s", name.c_str());
    out += line;
    for (size_t b = 0; b < sw->at("mean").size(); ++b) {
      const auto value = [&](const char* key) {
        const nlohmann::json& v = sw->at(key).at(b);
        return v.is_number() ? v.get<double>() : std::nan("");
      };
      std::snprintf(line, sizeof(line), " %5.3f [%5.3f, %5.3f]", value("mean"), value("min"), value("max"));
      out += line;
    }
    out += "\n";
  }
  return out;
}

// The 7-Scenes convention, one row per method: pose recall at 5 cm / 5 deg and the median errors
// over all query frames ("inf" when half of them or more have no pose); empty when no method has
// them.
std::string format_all_frames_table(const nlohmann::json& methods) {
  std::string out;
  char line[512];
  // A median over all frames: a number, "inf" / "nan" as written, "-" when missing.
  const auto median_text = [](const nlohmann::json& m, const char* key) -> std::string {
    const auto it = m.find(key);
    if (it == m.end() || it->is_null()) return "-";
    if (it->is_string()) return it->get<std::string>();
    char t[64];
    std::snprintf(t, sizeof(t), "%.3f", it->get<double>());
    return t;
  };
  for (const auto& [name, m] : methods.items()) {
    if (!m.contains("pose_recall_5cm_5deg")) continue;
    if (out.empty()) {
      out =
          "\npose over all query frames, the 7-Scenes convention (a frame without a pose counts as an infinite "
          "error):\n";
      std::snprintf(line, sizeof(line), "%-24s %8s %13s %13s\n", "method", "rec5/5", "med_pos_m_all", "med_rot_d_all");
      out += line;
    }
    std::snprintf(line, sizeof(line), "%-24s %8.4f %13s %13s\n", name.c_str(), scalar(m, "pose_recall_5cm_5deg"),
                  median_text(m, "median_position_error_all_frames_m").c_str(),
                  median_text(m, "median_rotation_error_all_frames_deg").c_str());
    out += line;
  }
  return out;
}

// The pose recall at each --pose-thresholds pair, one row per method; empty when every method has
// only the default pair (20 cm, 5 deg), which the main table's rec20/5 column already shows.
std::string format_thresholds_table(const nlohmann::json& methods) {
  const nlohmann::json* first = nullptr;
  for (const auto& [name, m] : methods.items()) {
    const auto at = m.find("pose_recall_at_thresholds");
    if (at == m.end() || !at->is_array() || at->empty()) continue;
    const bool only_default = at->size() == 1 && (*at)[0].at("max_position_error_m").get<double>() == 0.2 &&
                              (*at)[0].at("max_rotation_error_deg").get<double>() == 5.0;
    if (!only_default) {
      first = &*at;
      break;
    }
  }
  if (first == nullptr) return "";
  std::string out = "\npose recall at each --pose-thresholds pair (a frame is correct within the first):\n";
  char line[512];
  std::snprintf(line, sizeof(line), "%-24s", "method");
  out += line;
  for (const nlohmann::json& t : *first) {
    char label[64];
    std::snprintf(label, sizeof(label), "%g m, %g deg", t.at("max_position_error_m").get<double>(),
                  t.at("max_rotation_error_deg").get<double>());
    std::snprintf(line, sizeof(line), " %17s", label);
    out += line;
  }
  out += "\n";
  for (const auto& [name, m] : methods.items()) {
    const auto at = m.find("pose_recall_at_thresholds");
    if (at == m.end() || !at->is_array()) continue;
    std::snprintf(line, sizeof(line), "%-24s", name.c_str());
    out += line;
    for (const nlohmann::json& t : *at) {
      std::snprintf(line, sizeof(line), " %17.4f", scalar(t, "recall"));
      out += line;
    }
    out += "\n";
  }
  return out;
}

}  // namespace

std::string format_results_table(const nlohmann::json& report) {
  std::string out;
  char line[512];
  std::snprintf(line, sizeof(line), "%-24s %7s %7s %8s %7s %7s %7s %8s %7s %9s %9s %7s %10s %10s\n", "method", "P@1",
                "MRR", "MR@1FP", "m_prec", "m_rec", "bg_rej", "rec20/5", "AUC", "med_pos_m", "med_rot_d", "inlier",
                "match_ms", "total_ms");
  out += line;
  const auto methods = report.find("methods");
  if (methods == report.end() || !methods->is_object()) return out;
  for (const auto& [name, m] : methods->items()) {
    const auto mr = m.find("miss_rate_at_fppi");
    const double mr1 = (mr != m.end() && mr->is_object()) ? scalar(*mr, "1") : std::nan("");
    std::snprintf(line, sizeof(line),
                  "%-24s %7.4f %7.4f %8.4f %7.4f %7.4f %7.4f %8.4f %7.4f %9.3f %9.3f %7.4f %10.3f %10.3f\n",
                  name.c_str(), scalar(m, "precision_at_1"), scalar(m, "mrr"), mr1, scalar(m, "match_precision"),
                  scalar(m, "match_recall"), scalar(m, "background_rejection_rate"), scalar(m, "pose_recall_20cm_5deg"),
                  scalar(m, "pose_auc"), scalar(m, "median_position_error_m"), scalar(m, "median_rotation_error_deg"),
                  scalar(m, "mean_inlier_ratio"), scalar(m, "match_ms_per_frame"), scalar(m, "total_ms_per_frame"));
    out += line;
  }
  return out + format_all_frames_table(*methods) + format_thresholds_table(*methods) + format_sweep_table(*methods);
}

std::string format_generalization_gap(const nlohmann::json& report) {
  const auto gap = report.find("generalization_gap");
  if (gap == report.end() || !gap->contains("precision_at_1")) return "";
  const nlohmann::json& p1 = gap->at("precision_at_1");
  const nlohmann::json& pose = gap->at("pose_recall_20cm_5deg");
  std::vector<std::string> sessions;
  const auto reported = report.find("sessions");
  if (reported != report.end() && reported->is_array()) {
    for (const nlohmann::json& s : *reported) sessions.push_back(s.at("name").get<std::string>());
  }
  const auto value = [](const nlohmann::json& v) { return v.is_number() ? v.get<double>() : std::nan(""); };
  char cell[512];
  std::string out;
  const auto held = report.find("held_out_map_observations");
  if (held != report.end() && held->is_object()) {
    std::snprintf(cell, sizeof(cell),
                  "\ngeneralization gap: held-out map observations (%lld keypoints in %lld map frames, never "
                  "trained on) vs each unseen query session; P@1, pose recall at 20 cm / 5 deg:\n",
                  held->value("keypoints", 0LL), held->value("frames", 0LL));
  } else {
    std::snprintf(cell, sizeof(cell),
                  "\ngeneralization gap (held-out map observations: pass --run RUN_DIR); P@1, pose recall at "
                  "20 cm / 5 deg:\n");
  }
  out += cell;
  std::snprintf(cell, sizeof(cell), "%-24s %12s", "method", "held-out P@1");
  out += cell;
  for (const std::string& s : sessions) {
    std::snprintf(cell, sizeof(cell), " %16s %7s", (s + " P@1").c_str(), "pose");
    out += cell;
  }
  out += "\n";
  for (const auto& [name, row] : p1.items()) {
    const double h = value(row.at("held_out_map_observations"));
    if (std::isnan(h)) {
      std::snprintf(cell, sizeof(cell), "%-24s %12s", name.c_str(), "-");
    } else {
      std::snprintf(cell, sizeof(cell), "%-24s %12.4f", name.c_str(), h);
    }
    out += cell;
    for (const std::string& s : sessions) {
      const auto p = row.at("sessions").find(s);
      const double v = p == row.at("sessions").end() ? std::nan("") : value(*p);
      const double r = pose.contains(name) && pose.at(name).contains(s) ? value(pose.at(name).at(s)) : std::nan("");
      std::snprintf(cell, sizeof(cell), " %16.4f %7.4f", v, r);
      out += cell;
    }
    out += "\n";
  }
  return out;
}

std::string format_confidence_table(const nlohmann::json& report) {
  const auto methods = report.find("methods");
  if (methods == report.end() || !methods->is_object()) return "";
  std::string out;
  char cell[512];
  for (const auto& [name, m] : methods->items()) {
    const auto c = m.find("pose_confidence");
    if (c == m.end()) continue;
    if (out.empty()) {
      out +=
          "\nsuccess of reported poses (precision = right / reported, recall = right / frames, right = within the "
          "first pose thresholds); inlier rule vs the calibrated confidence at its operating point:\n";
      std::snprintf(cell, sizeof(cell), "%-24s %9s %10s %8s %9s %10s %8s %10s  %s\n", "method", "inl.prec",
                    "inl.recall", "inl.rep", "cal.prec", "cal.recall", "cal.rep", "threshold",
                    "over seeds: inlier prec / recall -> calibrated prec / recall (mean [min, max])");
      out += cell;
    }
    const nlohmann::json& inl = c->at("inlier_rule");
    if (!c->contains("calibrated_rule")) {
      std::snprintf(
          cell, sizeof(cell), "%-24s %9.4f %10.4f %8lld %9s %10s %8s %10s  (calibration not fitted: %lld poses)\n",
          name.c_str(), inl.at("precision").get<double>(), inl.at("recall").get<double>(),
          inl.at("frames_localized").get<long long>(), "-", "-", "-", "-", c->at("calibration").value("poses", 0LL));
      out += cell;
      continue;
    }
    const nlohmann::json& cal = c->at("calibrated_rule");
    std::snprintf(cell, sizeof(cell), "%-24s %9.4f %10.4f %8lld %9.4f %10.4f %8lld %10.4f", name.c_str(),
                  inl.at("precision").get<double>(), inl.at("recall").get<double>(),
                  inl.at("frames_localized").get<long long>(), cal.at("precision").get<double>(),
                  cal.at("recall").get<double>(), cal.at("frames_localized").get<long long>(),
                  cal.at("threshold").get<double>());
    out += cell;
    for (const nlohmann::json& b : c->value("sweep", nlohmann::json::array())) {
      if (!b.value("default_budget", false)) continue;
      const auto range = [&](const char* rule, const char* field) {
        double sum = 0, lo = 1e300, hi = -1e300;
        int n = 0;
        for (const nlohmann::json& s : b.at("seeds")) {
          const double v = s.at(rule).at(field).get<double>();
          sum += v;
          lo = std::min(lo, v);
          hi = std::max(hi, v);
          ++n;
        }
        char t[96];
        std::snprintf(t, sizeof(t), "%.3f [%.3f, %.3f]", n ? sum / n : 0.0, lo, hi);
        return std::string(t);
      };
      out += "  " + std::to_string(b.at("seeds").size()) + " seeds: " + range("inlier_rule", "precision") + " / " +
             range("inlier_rule", "recall") + " -> " + range("calibrated_rule", "precision") + " / " +
             range("calibrated_rule", "recall");
    }
    const auto outside = c->find("outside");
    if (outside != c->end() && outside->value("frames", 0LL) > 0) {
      out += "; outside frames localized " + std::to_string(outside->value("localized_inlier_rule", 0LL)) + "/" +
             std::to_string(outside->value("frames", 0LL)) + " -> " +
             std::to_string(outside->value("localized_calibrated", 0LL));
    }
    out += "\n";
  }
  return out;
}

}  // namespace lmb
