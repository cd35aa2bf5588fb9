// Per-round training log: one spdlog line and one metrics.jsonl line per round.
//   [time] round 12/2000 cost 1.234e+05 J 9.9e+04 val_p1 0.413 share 311 dim 4211>0 0.28 s/round ETA 9m
//   {"round":12,"cost":...,"squared_error":...,"validation_p1":0.413 (null if not evaluated),
//    "validation_p1_landmarks":0.52 (best landmark class, background left out),
//    "sharing_size":311,"dim":4211,"theta":0,"gain":...,"entries":...,"mined":0,
//    "seconds":0.28,"eta_seconds":556.1,"seconds_histogram":...,"seconds_search":...,
//    "seconds_update":...,"seconds_eval":...}
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "common/file_io.h"
#include "train/boost/stump_learner.h"

namespace lmb {

class RoundLogger {
 public:
  // Appends to `metrics_path` (empty = no file). Throws lmb::Error if it cannot be opened; log()
  // throws when a line cannot be written (a full disk), naming the file and the system's reason.
  RoundLogger(const std::filesystem::path& metrics_path, int32_t num_rounds);
  void log(const RoundStats& stats);
  // The JSON line for one round (no newline).
  static std::string json_line(const RoundStats& stats, double eta_seconds);

 private:
  AppendFile out_;
  int32_t num_rounds_;
  double total_seconds_ = 0.0;
  int64_t logged_ = 0;
};

}  // namespace lmb
