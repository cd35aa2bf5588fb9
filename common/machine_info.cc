#include "common/machine_info.h"

#include <fstream>
#include <thread>

namespace lmb {

std::string MachineInfo::summary() const {
  return cpu_model + ", " + std::to_string(logical_cores) + " logical cores";
}

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

}  // namespace lmb
