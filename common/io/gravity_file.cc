#include "common/io/gravity_file.h"
#include "common/text_parse.h"

#include <cmath>
#include <iomanip>
#include <sstream>
#include <vector>

#include "common/error.h"
#include "common/file_io.h"
#include "common/text_lines.h"

namespace lmb {

namespace fs = std::filesystem;

std::map<std::string, Eigen::Vector3d> read_gravity_file(const fs::path& path) {
  std::map<std::string, Eigen::Vector3d> gravity;
  for (TextLineReader lines(path); lines.next();) {
    const std::string at = lines.where();
    const std::vector<std::string> tokens = lines.tokens();
    LMB_CHECK(tokens.size() == 4, at << ": expected 4 fields (IMAGE_NAME GX GY GZ), got " << tokens.size());
    const Eigen::Vector3d g(parse_finite_number(tokens[1], at, "GX"), parse_finite_number(tokens[2], at, "GY"),
                            parse_finite_number(tokens[3], at, "GZ"));
    // Scaled by the largest component first: components near the double range (1e308) must not
    // overflow the norm (Eigen's stableNormalized does for 1.7e308).
    const double scale = g.cwiseAbs().maxCoeff();
    LMB_CHECK(scale > 0.0 && scale * (g / scale).norm() >= 1e-9,
              at << ": gravity of image " << tokens[0] << " is the zero vector");
    LMB_CHECK(gravity.emplace(tokens[0], (g / scale).normalized()).second,
              at << ": duplicate image name " << tokens[0]);
  }
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
  std::ostringstream out;
  out << "# Gravity direction (down) in each image's camera frame (x right, y down, z forward), any scale.\n"
      << "# IMAGE_NAME GX GY GZ\n";
  out << std::setprecision(17);
  for (const auto& [name, g] : gravity_in_cam) {
    LMB_CHECK(name.find_first_of(" \t\n") == std::string::npos,
              path.string() << ": image name '" << name << "' contains white space");
    out << name << ' ' << g.x() << ' ' << g.y() << ' ' << g.z() << '\n';
  }
  write_file_atomically(path, out.str());
}

}  // namespace lmb
