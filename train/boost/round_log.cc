#include "train/boost/round_log.h"

#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "common/error.h"

namespace lmb {

RoundLogger::RoundLogger(const std::filesystem::path& metrics_path, int32_t num_rounds) : num_rounds_(num_rounds) {
  if (!metrics_path.empty()) out_ = AppendFile(metrics_path);
}

std::string RoundLogger::json_line(const RoundStats& s, double eta_seconds) {
  nlohmann::json j;
  j["round"] = s.round;
  j["cost"] = s.cost;
  j["cost_before"] = s.cost_before;
  j["squared_error"] = s.squared_error;
  j["validation_p1"] = s.validation_p1 >= 0.0 ? nlohmann::json(s.validation_p1) : nlohmann::json(nullptr);
  j["validation_p1_landmarks"] =
      s.validation_p1_landmarks >= 0.0 ? nlohmann::json(s.validation_p1_landmarks) : nlohmann::json(nullptr);
  j["sharing_size"] = s.sharing_size;
  j["dim"] = s.dim;
  j["theta"] = s.theta;
  j["gain"] = s.gain;
  j["entries"] = s.num_entries;
  j["mined"] = s.mined;
  j["seconds"] = s.seconds;
  j["eta_seconds"] = eta_seconds;
  j["seconds_histogram"] = s.seconds_histogram;
  j["seconds_search"] = s.seconds_search;
  j["seconds_update"] = s.seconds_update;
  j["seconds_eval"] = s.seconds_eval;
  return j.dump();
}

void RoundLogger::log(const RoundStats& s) {
  total_seconds_ += s.seconds;
  ++logged_;
  const double eta = total_seconds_ / static_cast<double>(logged_) * std::max(0, num_rounds_ - (s.round + 1));
  std::string val = s.validation_p1 >= 0.0 ? fmt::format("{:.4f}", s.validation_p1) : std::string("-");
  spdlog::info("round {}/{} cost {:.6g} J {:.6g} val_p1 {} share {} dim {}>{} {:.3f} s/round ETA {:.0f} s", s.round + 1,
               num_rounds_, s.cost, s.squared_error, val, s.sharing_size, s.dim, s.theta, s.seconds, eta);
  if (out_.is_open()) out_.write(json_line(s, eta) + '\n');
}

}  // namespace lmb
