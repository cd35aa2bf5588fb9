#include "common/io/colmap_model.h"

#include <cmath>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>

#include "common/error.h"

namespace lmb {

namespace fs = std::filesystem;

namespace {

// Reads the non-comment, non-empty lines of a text file together with their line numbers.
std::vector<std::pair<int, std::string>> read_data_lines(const fs::path& path) {
  std::ifstream in(path);
  LMB_CHECK(in.good(), path.string() << ": cannot open file");
  std::vector<std::pair<int, std::string>> lines;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    lines.emplace_back(number, line);
  }
  return lines;
}

std::string where(const fs::path& path, int line) {
  return path.string() + " line " + std::to_string(line);
}

template <typename T>
T parse(std::istringstream& in, const std::string& at, const char* field) {
  T value{};
  in >> value;
  LMB_CHECK(!in.fail(), at << ": cannot read field '" << field << "'");
  return value;
}

double parse_finite(std::istringstream& in, const std::string& at, const char* field) {
  std::string token;
  in >> token;
  LMB_CHECK(!in.fail(), at << ": cannot read field '" << field << "'");
  size_t used = 0;
  double value = 0;
  try {
    value = std::stod(token, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  LMB_CHECK(used == token.size(), at << ": field '" << field << "' is not a number: '" << token << "'");
  LMB_CHECK(std::isfinite(value), at << ": field '" << field << "' is not finite");
  return value;
}

}  // namespace

Eigen::Quaterniond checked_rotation(double qw, double qx, double qy, double qz, const std::string& at) {
  const double norm = std::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
  LMB_CHECK(std::isfinite(norm), at << ": quaternion is not finite");
  LMB_CHECK(std::abs(norm - 1.0) < 1e-3,
            at << ": quaternion is not a rotation (norm " << norm << ", expected 1)");
  return Eigen::Quaterniond(qw / norm, qx / norm, qy / norm, qz / norm);
}

ColmapModel read_colmap_text(const fs::path& sparse_dir) {
  ColmapModel model;
  const fs::path cameras_path = sparse_dir / "cameras.txt";
  for (const auto& [number, line] : read_data_lines(cameras_path)) {
    const std::string at = where(cameras_path, number);
    std::istringstream in(line);
    Camera camera;
    const int id = parse<int>(in, at, "CAMERA_ID");
    camera.model = camera_model_from_name(parse<std::string>(in, at, "MODEL"));
    camera.width = parse<int>(in, at, "WIDTH");
    camera.height = parse<int>(in, at, "HEIGHT");
    std::string token;
    while (in >> token) {
      std::istringstream one(token);
      camera.params.push_back(parse_finite(one, at, "PARAMS[]"));
    }
    camera.check(at);
    LMB_CHECK(model.cameras.emplace(id, camera).second, at << ": duplicate camera id " << id);
  }

  const fs::path images_path = sparse_dir / "images.txt";
  const auto image_lines = read_data_lines(images_path);
  std::set<int> image_ids;
  std::set<std::string> names;
  // images.txt holds two lines per image; the second (2D points) may be empty, in which case
  // read_data_lines dropped it. A line whose first token count is 10 starts an image.
  for (const auto& [number, line] : image_lines) {
    const std::string at = where(images_path, number);
    std::istringstream probe(line);
    std::vector<std::string> tokens;
    std::string token;
    while (probe >> token) tokens.push_back(token);
    if (tokens.size() != 10) {
      // A POINTS2D line: triples of (x, y, point3D_id). The mapper re-detects keypoints, so they
      // are only validated for shape.
      LMB_CHECK(tokens.size() % 3 == 0 && !model.images.empty(),
                at << ": expected an image line with 10 fields or a POINTS2D line, got "
                   << tokens.size() << " fields");
      continue;
    }
    std::istringstream in(line);
    ColmapImage image;
    image.image_id = parse<int>(in, at, "IMAGE_ID");
    const double qw = parse_finite(in, at, "QW");
    const double qx = parse_finite(in, at, "QX");
    const double qy = parse_finite(in, at, "QY");
    const double qz = parse_finite(in, at, "QZ");
    image.cam_from_world.rotation = checked_rotation(qw, qx, qy, qz, at);
    image.cam_from_world.translation.x() = parse_finite(in, at, "TX");
    image.cam_from_world.translation.y() = parse_finite(in, at, "TY");
    image.cam_from_world.translation.z() = parse_finite(in, at, "TZ");
    image.camera_id = parse<int>(in, at, "CAMERA_ID");
    image.name = parse<std::string>(in, at, "NAME");
    LMB_CHECK(model.cameras.count(image.camera_id),
              at << ": image refers to camera " << image.camera_id << ", which cameras.txt lacks");
    LMB_CHECK(image_ids.insert(image.image_id).second, at << ": duplicate image id " << image.image_id);
    LMB_CHECK(names.insert(image.name).second, at << ": duplicate image name " << image.name);
    model.images.push_back(image);
  }
  std::sort(model.images.begin(), model.images.end(),
            [](const ColmapImage& a, const ColmapImage& b) { return a.image_id < b.image_id; });

  const fs::path points_path = sparse_dir / "points3D.txt";
  if (fs::exists(points_path)) {
    for (const auto& [number, line] : read_data_lines(points_path)) {
      const std::string at = where(points_path, number);
      std::istringstream in(line);
      ColmapPoint3D p;
      p.point3d_id = parse<int64_t>(in, at, "POINT3D_ID");
      p.xyz.x() = parse_finite(in, at, "X");
      p.xyz.y() = parse_finite(in, at, "Y");
      p.xyz.z() = parse_finite(in, at, "Z");
      for (int c = 0; c < 3; ++c) {
        const int v = parse<int>(in, at, "RGB");
        LMB_CHECK(v >= 0 && v <= 255, at << ": colour value " << v << " outside 0..255");
        p.rgb[c] = static_cast<uint8_t>(v);
      }
      p.error = parse_finite(in, at, "ERROR");
      model.points.push_back(p);
    }
  }
  return model;
}

void write_colmap_text(const ColmapModel& model, const fs::path& sparse_dir) {
  fs::create_directories(sparse_dir);
  {
    std::ofstream out(sparse_dir / "cameras.txt");
    out << "# Camera list with one line of data per camera:\n"
        << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
        << "# Number of cameras: " << model.cameras.size() << "\n";
    out << std::setprecision(17);
    for (const auto& [id, camera] : model.cameras) {
      out << id << ' ' << camera_model_name(camera.model) << ' ' << camera.width << ' ' << camera.height;
      for (double p : camera.params) out << ' ' << p;
      out << '\n';
    }
    LMB_CHECK(out.good(), (sparse_dir / "cameras.txt").string() << ": write failed");
  }
  {
    std::ofstream out(sparse_dir / "images.txt");
    out << "# Image list with two lines of data per image:\n"
        << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
        << "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
        << "# Number of images: " << model.images.size() << "\n";
    out << std::setprecision(17);
    for (const ColmapImage& im : model.images) {
      const Eigen::Quaterniond& q = im.cam_from_world.rotation;
      const Eigen::Vector3d& t = im.cam_from_world.translation;
      out << im.image_id << ' ' << q.w() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' '
          << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << im.camera_id << ' ' << im.name << "\n\n";
    }
    LMB_CHECK(out.good(), (sparse_dir / "images.txt").string() << ": write failed");
  }
  {
    std::ofstream out(sparse_dir / "points3D.txt");
    out << "# 3D point list with one line of data per point:\n"
        << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
        << "# Number of points: " << model.points.size() << "\n";
    out << std::setprecision(17);
    for (const ColmapPoint3D& p : model.points) {
      out << p.point3d_id << ' ' << p.xyz.x() << ' ' << p.xyz.y() << ' ' << p.xyz.z() << ' '
          << int(p.rgb[0]) << ' ' << int(p.rgb[1]) << ' ' << int(p.rgb[2]) << ' ' << p.error << '\n';
    }
    LMB_CHECK(out.good(), (sparse_dir / "points3D.txt").string() << ": write failed");
  }
}

}  // namespace lmb
