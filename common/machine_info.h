// The machine a figure was measured on, for reports and benchmarks: every figure comes with the
// machine it came from.
#pragma once

#include <cstdint>
#include <string>

namespace lmb {

struct MachineInfo {
  std::string cpu_model;        // /proc/cpuinfo "model name" of the first processor ("unknown" if absent)
  int logical_cores = 0;        // std::thread::hardware_concurrency()
  std::string summary() const;  // e.g. "AMD EPYC, 2 logical cores"
};

// Reads /proc/cpuinfo (Linux); never throws.
MachineInfo machine_info();

// The memory of this machine (Linux), for checks before a large allocation; never throws. Each
// figure is 0 when unknown.
struct MemoryInfo {
  int64_t total_bytes = 0;      // /proc/meminfo MemTotal, or the cgroup's memory limit if lower
  int64_t available_bytes = 0;  // what this process can still allocate: MemAvailable, less when the
                                // cgroup's limit or the address-space limit (ulimit -v) leave less
  std::string summary() const;  // e.g. "21.9 GB available of 23.5 GB"
};
MemoryInfo memory_info();

// This process's resources (Linux), for benchmarks and run summaries; never throw.
double cpu_seconds();     // CPU time of all its threads: fair on a shared machine
double peak_rss_mb();     // peak resident set (getrusage)
double current_rss_mb();  // resident set now (/proc/self/statm)

}  // namespace lmb
