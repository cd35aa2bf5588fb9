#include "common/io/colmap_model.h"
#include "common/text_parse.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>
#include <system_error>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/colmap_binary.h"
#include "common/text_lines.h"

namespace lmb {

namespace fs = std::filesystem;

namespace {

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
  return parse_finite_number(token, at, std::string("field '") + field + "'");
}

}  // namespace

std::string image_name_error(const std::string& name) {
  if (name.empty()) return "empty image name";
  const std::string quoted = "image name '" + name + "'";
  if (name.front() == '/') return quoted + " is an absolute path (names are relative to the image folder)";
  size_t begin = 0;
  while (begin <= name.size()) {
    size_t end = name.find('/', begin);
    if (end == std::string::npos) end = name.size();
    const std::string part = name.substr(begin, end - begin);
    if (part.empty()) return quoted + " has an empty path component";
    if (part == "..") return quoted + " leaves the image folder ('..' component)";
    if (part == ".") return quoted + " has a '.' path component";
    begin = end + 1;
  }
  return "";
}

void check_image_name(const std::string& name, const std::string& where) {
  const std::string why = image_name_error(name);
  LMB_CHECK(why.empty(), where << ": " << why);
}

Eigen::Quaterniond checked_rotation(double qw, double qx, double qy, double qz, const std::string& at) {
  const double norm = std::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
  LMB_CHECK(std::isfinite(norm), at << ": quaternion is not finite");
  LMB_CHECK(std::abs(norm - 1.0) < 1e-3, at << ": quaternion is not a rotation (norm " << norm << ", expected 1)");
  return Eigen::Quaterniond(qw / norm, qx / norm, qy / norm, qz / norm);
}

std::string colmap_track_error(const ColmapModel& model, const ColmapTrackElement& element) {
  const auto it = std::lower_bound(model.images.begin(), model.images.end(), element.image_id,
                                   [](const ColmapImage& im, int id) { return im.image_id < id; });
  if (it == model.images.end() || it->image_id != element.image_id) {
    return "track refers to image " + std::to_string(element.image_id) + ", which the model lacks";
  }
  if (!it->points2d.empty() &&
      (element.point2d_idx < 0 || static_cast<size_t>(element.point2d_idx) >= it->points2d.size())) {
    return "track refers to 2D point " + std::to_string(element.point2d_idx) + " of image " +
           std::to_string(element.image_id) + ", which has " + std::to_string(it->points2d.size());
  }
  return "";
}

ColmapModel read_colmap_text(const fs::path& sparse_dir) {
  ColmapModel model;
  for (TextLineReader lines(sparse_dir / "cameras.txt"); lines.next();) {
    const std::string at = lines.where();
    std::istringstream in(lines.line());
    Camera camera;
    const int id = parse<int>(in, at, "CAMERA_ID");
    LMB_CHECK(id >= 0, at << ": CAMERA_ID " << id << " is negative");
    camera.model = camera_model_from_name(parse<std::string>(in, at, "MODEL"), at);
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

  std::set<int> image_ids;
  std::set<std::string> names;
  // images.txt holds two lines per image; the second (2D points) may be empty, in which case
  // the line reader skipped it. A line with 10 fields starts an image; a POINTS2D line has a
  // multiple of 3 fields, so the two never look alike.
  bool points_allowed = false;
  for (TextLineReader lines(sparse_dir / "images.txt"); lines.next();) {
    const std::string at = lines.where();
    const std::string& line = lines.line();
    const std::vector<std::string> tokens = lines.tokens();
    if (tokens.size() != 10) {
      LMB_CHECK(tokens.size() % 3 == 0 && points_allowed,
                at << ": expected an image line with 10 fields or a POINTS2D line, got " << tokens.size() << " fields");
      points_allowed = false;
      std::vector<ColmapPoint2D>& points = model.images.back().points2d;
      points.reserve(tokens.size() / 3);
      std::istringstream in(line);
      for (size_t k = 0; k < tokens.size(); k += 3) {
        ColmapPoint2D p;
        p.xy.x() = parse_finite(in, at, "POINTS2D[].X");
        p.xy.y() = parse_finite(in, at, "POINTS2D[].Y");
        p.point3d_id = parse<int64_t>(in, at, "POINTS2D[].POINT3D_ID");
        LMB_CHECK(p.point3d_id >= -1, at << ": POINT3D_ID " << p.point3d_id << " is negative (only -1 means none)");
        points.push_back(p);
      }
      continue;
    }
    std::istringstream in(line);
    ColmapImage image;
    image.image_id = parse<int>(in, at, "IMAGE_ID");
    LMB_CHECK(image.image_id >= 0, at << ": IMAGE_ID " << image.image_id << " is negative");
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
    check_image_name(image.name, at);
    LMB_CHECK(model.cameras.count(image.camera_id),
              at << ": image refers to camera " << image.camera_id << ", which cameras.txt lacks");
    LMB_CHECK(image_ids.insert(image.image_id).second, at << ": duplicate image id " << image.image_id);
    LMB_CHECK(names.insert(image.name).second, at << ": duplicate image name " << image.name);
    model.images.push_back(image);
    points_allowed = true;
  }
  std::sort(model.images.begin(), model.images.end(),
            [](const ColmapImage& a, const ColmapImage& b) { return a.image_id < b.image_id; });

  const fs::path points_path = sparse_dir / "points3D.txt";
  if (fs::exists(points_path)) {
    for (TextLineReader lines(points_path); lines.next();) {
      const std::string at = lines.where();
      std::istringstream in(lines.line());
      ColmapPoint3D p;
      p.point3d_id = parse<int64_t>(in, at, "POINT3D_ID");
      LMB_CHECK(p.point3d_id >= 0, at << ": POINT3D_ID " << p.point3d_id << " is negative");
      p.xyz.x() = parse_finite(in, at, "X");
      p.xyz.y() = parse_finite(in, at, "Y");
      p.xyz.z() = parse_finite(in, at, "Z");
      for (int c = 0; c < 3; ++c) {
        const int v = parse<int>(in, at, "RGB");
        LMB_CHECK(v >= 0 && v <= 255, at << ": colour value " << v << " outside 0..255");
        p.rgb[c] = static_cast<uint8_t>(v);
      }
      p.error = parse_finite(in, at, "ERROR");
      std::string track_token;
      std::vector<std::string> track_tokens;
      while (in >> track_token) track_tokens.push_back(track_token);
      LMB_CHECK(track_tokens.size() % 2 == 0,
                at << ": TRACK[] must hold (IMAGE_ID, POINT2D_IDX) pairs, got " << track_tokens.size() << " values");
      for (size_t k = 0; k < track_tokens.size(); k += 2) {
        std::istringstream pair(track_tokens[k] + " " + track_tokens[k + 1]);
        ColmapTrackElement e;
        e.image_id = parse<int>(pair, at, "TRACK[].IMAGE_ID");
        e.point2d_idx = parse<int>(pair, at, "TRACK[].POINT2D_IDX");
        LMB_CHECK(e.point2d_idx >= 0, at << ": TRACK[].POINT2D_IDX " << e.point2d_idx << " is negative");
        const std::string why = colmap_track_error(model, e);
        LMB_CHECK(why.empty(), at << ": " << why);
        p.track.push_back(e);
      }
      model.points.push_back(p);
    }
  }
  return model;
}

void write_colmap_text(const ColmapModel& model, const fs::path& sparse_dir) {
  std::error_code ec;
  fs::create_directories(sparse_dir, ec);
  LMB_CHECK(!ec, sparse_dir.string() << ": cannot create the folder: " << ec.message());
  {
    std::ostringstream out;
    out << "# Camera list with one line of data per camera:\n"
        << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
        << "# Number of cameras: " << model.cameras.size() << "\n";
    out << std::setprecision(17);
    for (const auto& [id, camera] : model.cameras) {
      out << id << ' ' << camera_model_name(camera.model) << ' ' << camera.width << ' ' << camera.height;
      for (double p : camera.params) out << ' ' << p;
      out << '\n';
    }
    write_file_atomically(sparse_dir / "cameras.txt", out.str());
  }
  {
    std::ostringstream out;
    out << "# Image list with two lines of data per image:\n"
        << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
        << "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
        << "# Number of images: " << model.images.size() << "\n";
    out << std::setprecision(17);
    for (const ColmapImage& im : model.images) {
      const Eigen::Quaterniond& q = im.cam_from_world.rotation;
      const Eigen::Vector3d& t = im.cam_from_world.translation;
      out << im.image_id << ' ' << q.w() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << t.x() << ' ' << t.y()
          << ' ' << t.z() << ' ' << im.camera_id << ' ' << im.name << '\n';
      for (size_t k = 0; k < im.points2d.size(); ++k) {
        const ColmapPoint2D& p = im.points2d[k];
        out << (k ? " " : "") << p.xy.x() << ' ' << p.xy.y() << ' ' << p.point3d_id;
      }
      out << '\n';
    }
    write_file_atomically(sparse_dir / "images.txt", out.str());
  }
  {
    std::ostringstream out;
    out << "# 3D point list with one line of data per point:\n"
        << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
        << "# Number of points: " << model.points.size() << "\n";
    out << std::setprecision(17);
    for (const ColmapPoint3D& p : model.points) {
      out << p.point3d_id << ' ' << p.xyz.x() << ' ' << p.xyz.y() << ' ' << p.xyz.z() << ' ' << int(p.rgb[0]) << ' '
          << int(p.rgb[1]) << ' ' << int(p.rgb[2]) << ' ' << p.error;
      for (const ColmapTrackElement& e : p.track) out << ' ' << e.image_id << ' ' << e.point2d_idx;
      out << '\n';
    }
    write_file_atomically(sparse_dir / "points3D.txt", out.str());
  }
}

ColmapModel read_colmap_model(const fs::path& sparse_dir, ColmapFormat* format) {
  LMB_CHECK(fs::is_directory(sparse_dir), sparse_dir.string() << ": sparse model folder does not exist");
  const bool has_bin_cameras = fs::exists(sparse_dir / "cameras.bin");
  const bool has_bin_images = fs::exists(sparse_dir / "images.bin");
  if (has_bin_cameras || has_bin_images) {
    LMB_CHECK(has_bin_cameras && has_bin_images,
              sparse_dir.string() << ": incomplete binary model: " << (has_bin_cameras ? "images.bin" : "cameras.bin")
                                  << " is missing");
    if (format) *format = ColmapFormat::kBinary;
    return read_colmap_binary(sparse_dir);
  }
  LMB_CHECK(fs::exists(sparse_dir / "cameras.txt") || fs::exists(sparse_dir / "images.txt"),
            sparse_dir.string() << ": no COLMAP sparse model (expected cameras.bin + images.bin or "
                                   "cameras.txt + images.txt)");
  if (format) *format = ColmapFormat::kText;
  return read_colmap_text(sparse_dir);
}

namespace {

// True when `head` (the first bytes of a file) starts with the signature of an image format that
// OpenCV's imread decodes.
bool has_image_signature(const std::string& head) {
  auto starts = [&](const char* sig, size_t n, size_t offset = 0) {
    return head.size() >= offset + n && std::equal(sig, sig + n, head.begin() + static_cast<long>(offset));
  };
  if (starts("\xFF\xD8\xFF", 3)) return true;                                               // JPEG
  if (starts("\x89PNG\r\n\x1A\n", 8)) return true;                                          // PNG
  if (starts("II*\0", 4) || starts("MM\0*", 4)) return true;                                // TIFF
  if (starts("BM", 2)) return true;                                                         // BMP
  if (head.size() >= 2 && head[0] == 'P' && head[1] >= '1' && head[1] <= '7') return true;  // PNM, PAM
  if (starts("RIFF", 4) && starts("WEBP", 4, 8)) return true;                               // WebP
  if (starts("\0\0\0\x0CjP  ", 8) || starts("\xFF\x4F\xFF\x51", 4)) return true;            // JPEG 2000
  if (starts("\x76\x2F\x31\x01", 4)) return true;                                           // OpenEXR
  if (starts("#?RADIANCE", 10) || starts("#?RGBE", 6)) return true;                         // Radiance HDR
  if (starts("\x59\xA6\x6A\x95", 4)) return true;                                           // Sun raster
  return false;
}

}  // namespace

void check_collection_images(const ColmapModel& model, const fs::path& image_dir) {
  LMB_CHECK(fs::is_directory(image_dir), image_dir.string() << ": image folder does not exist");
  std::vector<const ColmapImage*> images;
  for (const ColmapImage& im : model.images) images.push_back(&im);
  std::sort(images.begin(), images.end(),
            [](const ColmapImage* a, const ColmapImage* b) { return a->image_id < b->image_id; });
  for (const ColmapImage* im : images) {
    const fs::path path = image_dir / im->name;
    const std::string at = "image " + std::to_string(im->image_id) + " '" + im->name + "': " + path.string();
    std::error_code ec;
    if (!fs::exists(path, ec)) {
      if (fs::is_symlink(fs::symlink_status(path, ec))) {
        LMB_FAIL(at << ": dangling symbolic link to " << fs::read_symlink(path, ec).string());
      }
      LMB_FAIL(at << ": image file is missing");
    }
    LMB_CHECK(fs::is_regular_file(path, ec), at << ": not a regular file");
    std::ifstream in(path, std::ios::binary);
    LMB_CHECK(in.good(), at << ": cannot open the file for reading");
    std::string head(16, '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<size_t>(in.gcount()));
    LMB_CHECK(!head.empty(), at << ": empty file");
    LMB_CHECK(has_image_signature(head), at << ": not an image file (unknown signature)");
  }
}

}  // namespace lmb
