// The files the commands read that no option names itself (a bundle's area models), for
// check_outputs_not_inputs (common/file_io.h).
#include <filesystem>
#include <regex>
#include <string>
#include <system_error>
#include <vector>

#include "common/error.h"
#include "infer/area_bundle.h"
#include "train/cli/cli_util.h"

namespace lmb::cli {

std::vector<NamedPath> bundle_input_paths(const std::string& index, const std::string& what) {
  std::vector<NamedPath> paths;
  if (index.empty()) return paths;
  paths.push_back({index, what});
  try {
    const auto bundle = AreaBundle::open(index);
    const std::filesystem::path folder = std::filesystem::path(index).parent_path();
    for (const BundleArea& area : bundle->areas()) paths.push_back({folder / area.file, what});
  } catch (const Error&) {
    // The index alone: its reader says what is wrong with it when the command opens it.
  }
  return paths;
}

std::vector<NamedPath> area_model_paths(const std::string& folder, const std::string& what) {
  std::vector<NamedPath> paths;
  if (folder.empty()) return paths;
  static const std::regex name("area-[0-9]+\\.lbm");
  std::error_code ec;
  for (std::filesystem::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    if (std::regex_match(it->path().filename().string(), name)) paths.push_back({it->path(), what});
  }
  return paths;
}

}  // namespace lmb::cli
