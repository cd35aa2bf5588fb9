// The machine a figure was measured on, for reports and benchmarks: every figure comes with the
// machine it came from.
#pragma once

#include <string>

namespace lmb {

struct MachineInfo {
  std::string cpu_model;        // /proc/cpuinfo "model name" of the first processor ("unknown" if absent)
  int logical_cores = 0;        // std::thread::hardware_concurrency()
  std::string summary() const;  // e.g. "AMD EPYC, 2 logical cores"
};

// Reads /proc/cpuinfo (Linux); never throws.
MachineInfo machine_info();

// This process's resources (Linux), for benchmarks and run summaries; never throw.
double cpu_seconds();     // CPU time of all its threads: fair on a shared machine
double peak_rss_mb();     // peak resident set (getrusage)
double current_rss_mb();  // resident set now (/proc/self/statm)

}  // namespace lmb
