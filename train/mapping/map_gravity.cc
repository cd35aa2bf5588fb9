#include "train/mapping/map_gravity.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <vector>

#include "common/error.h"
#include "common/io/colmap_model.h"
#include "common/io/gravity_file.h"
#include "train/mapping/mapper.h"

namespace lmb {

namespace fs = std::filesystem;

namespace {

std::string fixed(double v, int digits) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

}  // namespace

MapGravityChoice choose_map_gravity(const MapGravityRequest& request) {
  MapGravityChoice choice;
  choice.up = parse_up_axis(request.up);
  const std::string up_text = "-up of --up " + request.up + (request.up_given ? "" : " (the default)");

  if (!request.gravity.empty() && request.gravity != "none") {
    LMB_CHECK(!request.up_given, "--gravity " << request.gravity << " and --up " << request.up
                                              << " are exclusive: the file gives every image's gravity");
    LMB_CHECK(fs::is_regular_file(request.gravity), "--gravity: " << request.gravity << ": no such file");
    choice.gravity_file = request.gravity;
    choice.description = "per image from " + request.gravity + " (--gravity)";
    return choice;
  }
  const fs::path found = request.collection / "gravity.txt";
  const bool has_file = fs::exists(found);
  if (request.gravity == "none") {
    choice.description = up_text + (has_file ? " (--gravity none: " + found.string() + " is not used)" : "");
    return choice;
  }
  if (!has_file) {
    choice.description = up_text + " (no " + found.string() + ")";
    return choice;
  }
  if (!request.up_given) {
    choice.gravity_file = found;
    choice.description =
        "per image from " + found.string() + " (found in the collection; --gravity none uses --up instead)";
    return choice;
  }

  // Both an explicit axis and the collection's file: compare them image by image.
  const ColmapModel model = read_colmap_model(request.collection / "sparse");
  const std::map<std::string, Eigen::Vector3d> gravity = read_gravity_file(found, model);
  std::vector<double> angles;
  for (const ColmapImage& image : model.images) {
    const Eigen::Vector3d from_up = (image.cam_from_world.rotation * (-choice.up)).normalized();
    const double cosine = std::clamp(from_up.dot(gravity.at(image.name)), -1.0, 1.0);
    angles.push_back(std::acos(cosine) * 180.0 / M_PI);
  }
  LMB_CHECK(!angles.empty(), found.string() << ": the sparse model has no images");
  std::sort(angles.begin(), angles.end());
  const size_t n = angles.size();
  choice.images_compared = static_cast<int>(n);
  choice.median_angle_deg = n % 2 ? angles[n / 2] : 0.5 * (angles[n / 2 - 1] + angles[n / 2]);
  choice.max_angle_deg = angles.back();
  LMB_CHECK(choice.median_angle_deg <= kMaxGravityDisagreementDeg,
            "--up " << request.up << " disagrees with " << found.string() << " by a median "
                    << fixed(choice.median_angle_deg, 1) << " deg over " << n
                    << " images: drop --up to use the file, or pass --gravity none to use --up");
  choice.description = up_text + " (" + found.string() + " agrees: median " + fixed(choice.median_angle_deg, 1) +
                       " deg, max " + fixed(choice.max_angle_deg, 1) + " deg over " + std::to_string(n) +
                       " images; drop --up to use the file)";
  return choice;
}

}  // namespace lmb
