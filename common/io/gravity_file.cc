#include "common/text_parse.h"
#include "common/io/gravity_file.h"

#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <vector>

#include "common/error.h"

namespace lmb {

namespace fs = std::filesystem;

std::map<std::string, Eigen::Vector3d> read_gravity_file(const fs::path& path) {
  std::ifstream in(path);
  LMB_CHECK(in.good(), path.string() << ": cannot open gravity file");
  std::map<std::string, Eigen::Vector3d> gravity;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string at = path.string() + " line " + std::to_string(number);
    std::istringstream fields(line);
    std::vector<std::string> tokens;
    std::string token;
    while (fields >> token) tokens.push_back(token);
    LMB_CHECK(tokens.size() == 4, at << ": expected 4 fields (IMAGE_NAME GX GY GZ), got " << tokens.size());
    const Eigen::Vector3d g(parse_finite_number(tokens[1], at, "GX"), parse_finite_number(tokens[2], at, "GY"),
                            parse_finite_number(tokens[3], at, "GZ"));
    // Scaled by the largest component first: components near the double range (1e308) must not
    // overflow the norm (Eigen's stableNormalized does for 1.7e308).
    const double scale = g.cwiseAbs().maxCoeff();
    LMB_CHECK(scale > 0.0 && scale * (g / scale).norm() >= 1e-9,
              at << ": gravity of image " << tokens[0] << " is the zero vector");
    LMB_CHECK(gravity.emplace(tokens[0], (g / scale).normalized()).second, at << ": duplicate image name " << tokens[0]);
  }
  LMB_CHECK(!in.bad(), path.string() << ": read error");
  return gravity;
}

std::map<std::string, Eigen::Vector3d> read_gravity_file(const fs::path& path, const ColmapModel& model) {
  std::map<std::string, Eigen::Vector3d> gravity = read_gravity_file(path);
  std::map<std::string, int> image_ids;
  for (const ColmapImage& im : model.images) image_ids[im.name] = im.image_id;
  for (const auto& [name, g] : gravity) {
    LMB_CHECK(image_ids.count(name), path.string() << ": image name " << name << " is not in the sparse model");
  }
  for (const ColmapImage& im : model.images) {
    LMB_CHECK(gravity.count(im.name),
              path.string() << ": no gravity for image " << im.name << " (image id " << im.image_id << ")");
  }
  return gravity;
}

void write_gravity_file(const std::map<std::string, Eigen::Vector3d>& gravity_in_cam, const fs::path& path) {
  std::ofstream out(path, std::ios::trunc);
  LMB_CHECK(out.good(), path.string() << ": cannot open for writing");
  out << "# Gravity direction (down) in each image's camera frame (x right, y down, z forward), any scale.\n"
      << "# IMAGE_NAME GX GY GZ\n";
  out << std::setprecision(17);
  for (const auto& [name, g] : gravity_in_cam) {
    LMB_CHECK(name.find_first_of(" \t\n") == std::string::npos,
              path.string() << ": image name '" << name << "' contains white space");
    out << name << ' ' << g.x() << ' ' << g.y() << ' ' << g.z() << '\n';
  }
  out.close();
  LMB_CHECK(out.good(), path.string() << ": write failed");
}

}  // namespace lmb
