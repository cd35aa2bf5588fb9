#include "common/machine_info.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <thread>

namespace lmb {

std::string MachineInfo::summary() const { return cpu_model + ", " + std::to_string(logical_cores) + " logical cores"; }

MachineInfo machine_info() {
  MachineInfo m;
  m.cpu_model = "unknown";
  m.logical_cores = static_cast<int>(std::thread::hardware_concurrency());
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) != 0) continue;
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const size_t begin = line.find_first_not_of(" \t", colon + 1);
    if (begin != std::string::npos) m.cpu_model = line.substr(begin);
    break;
  }
  return m;
}

namespace {

// The first number of a file (e.g. a cgroup's memory.max), or -1 ("max", missing, unreadable).
int64_t read_number(const char* path) {
  std::ifstream in(path);
  int64_t value = -1;
  if (!(in >> value)) return -1;
  return value;
}

// A /proc/meminfo field in bytes, or -1.
int64_t meminfo_bytes(const std::string& field) {
  std::ifstream in("/proc/meminfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(field + ":", 0) != 0) continue;
    return std::strtoll(line.c_str() + field.size() + 1, nullptr, 10) * 1024;
  }
  return -1;
}

std::string gigabytes(int64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f GB", static_cast<double>(bytes) / 1e9);
  return text;
}

}  // namespace

std::string MemoryInfo::summary() const {
  if (total_bytes <= 0 && available_bytes <= 0) return "memory unknown";
  return gigabytes(available_bytes) + " available of " + gigabytes(total_bytes);
}

MemoryInfo memory_info() {
  MemoryInfo m;
  m.total_bytes = std::max<int64_t>(0, meminfo_bytes("MemTotal"));
  m.available_bytes = std::max<int64_t>(0, meminfo_bytes("MemAvailable"));
  auto cap = [&m](int64_t limit, int64_t used) {
    if (limit <= 0 || limit >= (int64_t{1} << 60)) return;  // no limit
    m.total_bytes = m.total_bytes > 0 ? std::min(m.total_bytes, limit) : limit;
    const int64_t left = std::max<int64_t>(0, limit - std::max<int64_t>(0, used));
    m.available_bytes = m.available_bytes > 0 ? std::min(m.available_bytes, left) : left;
  };
  // cgroup v2, then v1.
  cap(read_number("/sys/fs/cgroup/memory.max"), read_number("/sys/fs/cgroup/memory.current"));
  cap(read_number("/sys/fs/cgroup/memory/memory.limit_in_bytes"),
      read_number("/sys/fs/cgroup/memory/memory.usage_in_bytes"));
  rlimit as{};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    std::ifstream statm("/proc/self/statm");
    int64_t pages = 0;
    statm >> pages;
    const int64_t limit = static_cast<int64_t>(std::min<rlim_t>(as.rlim_cur, rlim_t{1} << 62));
    const int64_t left = std::max<int64_t>(0, limit - pages * static_cast<int64_t>(::sysconf(_SC_PAGESIZE)));
    m.available_bytes = m.available_bytes > 0 ? std::min(m.available_bytes, left) : left;
  }
  return m;
}

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

double current_rss_mb() {
  std::ifstream statm("/proc/self/statm");
  long pages = 0, resident = 0;
  statm >> pages >> resident;
  return static_cast<double>(resident) * static_cast<double>(::sysconf(_SC_PAGESIZE)) / 1048576.0;
}

}  // namespace lmb
