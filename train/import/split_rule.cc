#include "train/import/split_rule.h"

#include <cmath>
#include <map>
#include <sstream>

#include "common/error.h"
#include "common/text_lines.h"
#include "common/text_parse.h"

namespace lmb {

SplitRule parse_split_rule(const std::string& text) {
  SplitRule rule;
  const size_t colon = text.find(':');
  LMB_CHECK(colon != std::string::npos,
            "--split '" << text << "': expected every:N, first:F, time:A:B, map-list:FILE or query-list:FILE");
  const std::string kind = text.substr(0, colon);
  const std::string arg = text.substr(colon + 1);
  if (kind == "every") {
    rule.kind = SplitRule::Kind::kEvery;
    const double n = parse_finite_number(arg, "--split '" + text + "'", "N");
    LMB_CHECK(n >= 1 && n == std::floor(n) && n < 1e9, "--split '" << text << "': N must be an integer >= 1");
    rule.every = static_cast<int>(n);
  } else if (kind == "first") {
    rule.kind = SplitRule::Kind::kFirst;
    rule.first_fraction = parse_finite_number(arg, "--split '" + text + "'", "F");
    LMB_CHECK(rule.first_fraction > 0 && rule.first_fraction <= 1, "--split '" << text << "': F must be in (0, 1]");
  } else if (kind == "time") {
    rule.kind = SplitRule::Kind::kTime;
    const size_t second = arg.find(':');
    LMB_CHECK(second != std::string::npos, "--split '" << text << "': expected time:A:B (seconds)");
    rule.time_begin_s = parse_finite_number(arg.substr(0, second), "--split '" + text + "'", "A");
    rule.time_end_s = parse_finite_number(arg.substr(second + 1), "--split '" + text + "'", "B");
    LMB_CHECK(rule.time_begin_s < rule.time_end_s, "--split '" << text << "': A must be smaller than B");
  } else if (kind == "list" || kind == "map-list" || kind == "query-list") {
    rule.kind = SplitRule::Kind::kList;
    rule.list_names_queries = kind == "query-list";
    rule.list_file = arg;
    LMB_CHECK(!arg.empty(), "--split '" << text << "': no list file named");
    std::set<std::string> seen;
    try {
      for (TextLineReader lines(rule.list_file); lines.next();) {
        const std::string entry = lines.tokens().front();
        LMB_CHECK(seen.insert(entry).second, lines.where() << ": duplicate entry " << entry);
        rule.list.push_back(entry);
      }
    } catch (const Error& e) {
      LMB_FAIL("--split '" << text << "': " << e.what());
    }
    LMB_CHECK(!rule.list.empty(), arg << ": the split list names no frame");
  } else {
    LMB_FAIL("--split '" << text << "': unknown rule '" << kind
                         << "' (expected every, first, time, map-list, query-list or list)");
  }
  return rule;
}

std::vector<bool> assign_map_frames(const SplitRule& rule, const std::vector<SplitFrame>& frames,
                                    bool frames_have_time) {
  const size_t n = frames.size();
  std::vector<bool> is_map(n, false);
  switch (rule.kind) {
    case SplitRule::Kind::kEvery:
      for (size_t i = 0; i < n; ++i) is_map[i] = i % static_cast<size_t>(rule.every) == 0;
      break;
    case SplitRule::Kind::kFirst: {
      const size_t count = static_cast<size_t>(std::llround(rule.first_fraction * static_cast<double>(n)));
      for (size_t i = 0; i < n && i < count; ++i) is_map[i] = true;
      break;
    }
    case SplitRule::Kind::kTime: {
      LMB_CHECK(frames_have_time, "--split time:A:B needs frame timestamps, which this collection lacks");
      if (n == 0) break;
      const double t0 = frames.front().time_s;
      for (size_t i = 0; i < n; ++i) {
        const double t = frames[i].time_s - t0;
        is_map[i] = t >= rule.time_begin_s && t < rule.time_end_s;
      }
      break;
    }
    case SplitRule::Kind::kList: {
      std::map<std::string, size_t> by_key;
      for (size_t i = 0; i < n; ++i) {
        for (const std::string& key : frames[i].keys) by_key.emplace(key, i);
      }
      if (rule.list_names_queries) is_map.assign(n, true);
      for (const std::string& entry : rule.list) {
        const auto it = by_key.find(entry);
        LMB_CHECK(it != by_key.end(), rule.list_file.string() << ": entry '" << entry << "' names no frame");
        is_map[it->second] = !rule.list_names_queries;
      }
      break;
    }
  }
  bool any = false;
  for (bool b : is_map) any = any || b;
  LMB_CHECK(n == 0 || any, "--split: the rule leaves no map frame among " << n << " frames");
  return is_map;
}

}  // namespace lmb
