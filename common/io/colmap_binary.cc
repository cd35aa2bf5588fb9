#include "common/io/colmap_binary.h"

#include <algorithm>
#include <bit>
#include <climits>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <sstream>
#include <system_error>

#include "common/error.h"
#include "common/file_io.h"

namespace lmb {

namespace fs = std::filesystem;

namespace {

static_assert(std::endian::native == std::endian::little || std::endian::native == std::endian::big,
              "mixed-endian platforms are not supported");

template <typename T>
T from_little_endian(T value) {
  if constexpr (std::endian::native == std::endian::big) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    std::reverse(bytes, bytes + sizeof(T));
    std::memcpy(&value, bytes, sizeof(T));
  }
  return value;
}

// Minimum sizes of one record, for bounding counts before allocating.
constexpr uint64_t kMinCameraBytes = 4 + 4 + 8 + 8 + 3 * 8;  // the smallest model has 3 params
constexpr uint64_t kMinImageBytes = 4 + 7 * 8 + 4 + 1 + 8;   // empty name: only its NUL
constexpr uint64_t kPoint2DBytes = 3 * 8;
constexpr uint64_t kMinPoint3DBytes = 8 + 3 * 8 + 3 + 8 + 8;
constexpr uint64_t kTrackElementBytes = 4 + 4;
constexpr uint64_t kNoPoint3DId = std::numeric_limits<uint64_t>::max();

// COLMAP's camera model ids this project cannot represent, for a message that names them.
const char* colmap_model_name_for_id(int id) {
  switch (id) {
    case 5: return "OPENCV_FISHEYE";
    case 7: return "FOV";
    case 8: return "SIMPLE_RADIAL_FISHEYE";
    case 9: return "RADIAL_FISHEYE";
    case 10: return "THIN_PRISM_FISHEYE";
    case 11: return "RAD_TAN_THIN_PRISM_FISHEYE";
    default: return nullptr;
  }
}

// A bounds-checked little-endian cursor over one whole file. Every failure names the file, the
// current record and the byte offset.
class BinaryReader {
 public:
  explicit BinaryReader(const fs::path& path) : path_(path), bytes_(read_file(path)) {}

  void set_record(const std::string& record) { record_ = record; }
  uint64_t offset() const { return pos_; }
  uint64_t bytes_left() const { return bytes_.size() - pos_; }

  [[noreturn]] void fail(const std::string& reason) const {
    LMB_FAIL(path_.string() << ": " << (record_.empty() ? std::string() : record_ + ": ") << reason
                            << " (at byte offset " << pos_ << " of " << bytes_.size() << ")");
  }

  template <typename T>
  T read(const char* field) {
    if (bytes_left() < sizeof(T)) {
      fail(std::string("truncated file: cannot read ") + field + " (" + std::to_string(sizeof(T)) + " bytes needed, " +
           std::to_string(bytes_left()) + " left)");
    }
    T value;
    std::memcpy(&value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return from_little_endian(value);
  }

  double read_finite(const char* field) {
    const double value = read<double>(field);
    if (!std::isfinite(value)) fail(std::string(field) + " is not finite");
    return value;
  }

  // A count followed by records of at least `min_record_bytes` each; checked against the bytes
  // left so that a corrupt count cannot trigger a huge allocation.
  uint64_t read_count(const char* field, uint64_t min_record_bytes) {
    const uint64_t count = read<uint64_t>(field);
    if (count > bytes_left() / min_record_bytes) {
      fail(std::string(field) + " is " + std::to_string(count) + " but only " + std::to_string(bytes_left()) +
           " bytes are left (at least " + std::to_string(min_record_bytes) + " per record)");
    }
    return count;
  }

  std::string read_name(const char* field) {
    const auto begin = bytes_.begin() + static_cast<std::ptrdiff_t>(pos_);
    const auto nul = std::find(begin, bytes_.end(), '\0');
    if (nul == bytes_.end()) fail(std::string("truncated file: ") + field + " has no NUL terminator");
    std::string name(begin, nul);
    pos_ += name.size() + 1;
    return name;
  }

  int read_id32(const char* field) {
    const uint32_t id = read<uint32_t>(field);
    if (id > static_cast<uint32_t>(INT_MAX)) fail(std::string(field) + " " + std::to_string(id) + " is too large");
    return static_cast<int>(id);
  }

  void expect_end() const {
    if (bytes_left() != 0) {
      fail(std::to_string(bytes_left()) + " trailing bytes after the last record (wrong count?)");
    }
  }

 private:
  fs::path path_;
  std::string bytes_;
  uint64_t pos_ = 0;
  std::string record_;
};

std::string record_name(const char* kind, uint64_t index, int64_t id) {
  std::ostringstream s;
  s << kind << " record " << index;
  if (id >= 0) s << " (id " << id << ")";
  return s.str();
}

void read_cameras(const fs::path& path, ColmapModel* model) {
  BinaryReader in(path);
  const uint64_t count = in.read_count("number of cameras", kMinCameraBytes);
  for (uint64_t i = 0; i < count; ++i) {
    in.set_record(record_name("camera", i, -1));
    const int id = in.read_id32("camera_id");
    in.set_record(record_name("camera", i, id));
    const int32_t model_id = in.read<int32_t>("model_id");
    Camera camera;
    if (model_id != 0 && model_id != 1 && model_id != 2 && model_id != 3 && model_id != 4 && model_id != 6) {
      const char* name = colmap_model_name_for_id(model_id);
      if (name) {
        in.fail("unsupported camera model id " + std::to_string(model_id) + " (" + name +
                "); supported: 0 SIMPLE_PINHOLE, 1 PINHOLE, 2 SIMPLE_RADIAL, 3 RADIAL, 4 OPENCV, 6 FULL_OPENCV");
      }
      in.fail("unknown camera model id " + std::to_string(model_id));
    }
    camera.model = camera_model_from_id(model_id);
    const uint64_t width = in.read<uint64_t>("width");
    const uint64_t height = in.read<uint64_t>("height");
    if (width == 0 || height == 0 || width > static_cast<uint64_t>(INT_MAX) ||
        height > static_cast<uint64_t>(INT_MAX)) {
      in.fail("image size " + std::to_string(width) + "x" + std::to_string(height) + " is invalid");
    }
    camera.width = static_cast<int>(width);
    camera.height = static_cast<int>(height);
    const int num_params = camera_model_num_params(camera.model);
    for (int k = 0; k < num_params; ++k) camera.params.push_back(in.read_finite("camera parameter"));
    std::ostringstream at;
    at << path.string() << ": " << record_name("camera", i, id);
    camera.check(at.str());
    if (!model->cameras.emplace(id, camera).second) in.fail("duplicate camera id " + std::to_string(id));
  }
  in.set_record("");
  in.expect_end();
}

void read_images(const fs::path& path, ColmapModel* model) {
  BinaryReader in(path);
  const uint64_t count = in.read_count("number of images", kMinImageBytes);
  std::set<int> ids;
  std::set<std::string> names;
  model->images.reserve(count);
  for (uint64_t i = 0; i < count; ++i) {
    in.set_record(record_name("image", i, -1));
    ColmapImage image;
    image.image_id = in.read_id32("image_id");
    const std::string record = record_name("image", i, image.image_id);
    in.set_record(record);
    double q[4];
    for (double& v : q) v = in.read_finite("quaternion component");
    std::ostringstream at;
    at << path.string() << ": " << record;
    image.cam_from_world.rotation = checked_rotation(q[0], q[1], q[2], q[3], at.str());
    for (int k = 0; k < 3; ++k) image.cam_from_world.translation[k] = in.read_finite("translation component");
    image.camera_id = in.read_id32("camera_id");
    image.name = in.read_name("image name");
    if (const std::string why = image_name_error(image.name); !why.empty()) in.fail(why);
    if (!model->cameras.count(image.camera_id)) {
      in.fail("image refers to camera " + std::to_string(image.camera_id) + ", which cameras.bin lacks");
    }
    if (!ids.insert(image.image_id).second) in.fail("duplicate image id " + std::to_string(image.image_id));
    if (!names.insert(image.name).second) in.fail("duplicate image name " + image.name);
    const uint64_t num_points = in.read_count("number of 2D points", kPoint2DBytes);
    image.points2d.resize(num_points);
    for (ColmapPoint2D& p : image.points2d) {
      p.xy.x() = in.read_finite("2D point x");
      p.xy.y() = in.read_finite("2D point y");
      const uint64_t id = in.read<uint64_t>("2D point's point3D_id");
      if (id != kNoPoint3DId && id > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) {
        in.fail("2D point's point3D_id " + std::to_string(id) + " is too large");
      }
      p.point3d_id = id == kNoPoint3DId ? ColmapPoint2D::kNoPoint3D : static_cast<int64_t>(id);
    }
    model->images.push_back(std::move(image));
  }
  in.set_record("");
  in.expect_end();
  std::sort(model->images.begin(), model->images.end(),
            [](const ColmapImage& a, const ColmapImage& b) { return a.image_id < b.image_id; });
}

void read_points(const fs::path& path, ColmapModel* model) {
  BinaryReader in(path);
  const uint64_t count = in.read_count("number of 3D points", kMinPoint3DBytes);
  model->points.reserve(count);
  for (uint64_t i = 0; i < count; ++i) {
    in.set_record(record_name("point3D", i, -1));
    ColmapPoint3D p;
    const uint64_t id = in.read<uint64_t>("point3D_id");
    if (id > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) {
      in.fail("point3D_id " + std::to_string(id) + " is too large");
    }
    p.point3d_id = static_cast<int64_t>(id);
    in.set_record(record_name("point3D", i, p.point3d_id));
    for (int k = 0; k < 3; ++k) p.xyz[k] = in.read_finite("coordinate");
    for (int k = 0; k < 3; ++k) p.rgb[k] = in.read<uint8_t>("colour");
    p.error = in.read_finite("error");
    const uint64_t track_length = in.read_count("track length", kTrackElementBytes);
    p.track.resize(track_length);
    for (ColmapTrackElement& e : p.track) {
      e.image_id = in.read_id32("track image_id");
      e.point2d_idx = in.read_id32("track point2D_idx");
      const std::string why = colmap_track_error(*model, e);
      if (!why.empty()) in.fail(why);
    }
    model->points.push_back(std::move(p));
  }
  in.set_record("");
  in.expect_end();
}

// Little-endian appends for the writer.
class BinaryWriter {
 public:
  template <typename T>
  void put(T value) {
    value = from_little_endian(value);  // the same byte swap converts both ways
    const char* p = reinterpret_cast<const char*>(&value);
    bytes_.insert(bytes_.end(), p, p + sizeof(T));
  }
  void put_name(const std::string& name) {
    bytes_.insert(bytes_.end(), name.begin(), name.end());
    bytes_.push_back('\0');
  }
  void save(const fs::path& path) const { write_file_atomically(path, bytes_.data(), bytes_.size()); }

 private:
  std::vector<char> bytes_;
};

uint32_t checked_u32(int64_t id, const char* what) {
  LMB_CHECK(id >= 0 && id <= static_cast<int64_t>(std::numeric_limits<uint32_t>::max()),
            "write_colmap_binary: " << what << " " << id << " does not fit COLMAP's uint32 id");
  return static_cast<uint32_t>(id);
}

}  // namespace

ColmapModel read_colmap_binary(const fs::path& sparse_dir) {
  ColmapModel model;
  read_cameras(sparse_dir / "cameras.bin", &model);
  read_images(sparse_dir / "images.bin", &model);
  if (fs::exists(sparse_dir / "points3D.bin")) read_points(sparse_dir / "points3D.bin", &model);
  return model;
}

void write_colmap_binary(const ColmapModel& model, const fs::path& sparse_dir) {
  std::error_code ec;
  fs::create_directories(sparse_dir, ec);
  LMB_CHECK(!ec, sparse_dir.string() << ": cannot create the folder: " << ec.message());
  {
    BinaryWriter out;
    out.put<uint64_t>(model.cameras.size());
    for (const auto& [id, camera] : model.cameras) {
      out.put<uint32_t>(checked_u32(id, "camera id"));
      out.put<int32_t>(static_cast<int32_t>(camera.model));
      out.put<uint64_t>(static_cast<uint64_t>(camera.width));
      out.put<uint64_t>(static_cast<uint64_t>(camera.height));
      for (double p : camera.params) out.put<double>(p);
    }
    out.save(sparse_dir / "cameras.bin");
  }
  {
    BinaryWriter out;
    out.put<uint64_t>(model.images.size());
    for (const ColmapImage& im : model.images) {
      out.put<uint32_t>(checked_u32(im.image_id, "image id"));
      const Eigen::Quaterniond& q = im.cam_from_world.rotation;
      out.put<double>(q.w());
      out.put<double>(q.x());
      out.put<double>(q.y());
      out.put<double>(q.z());
      for (int k = 0; k < 3; ++k) out.put<double>(im.cam_from_world.translation[k]);
      out.put<uint32_t>(checked_u32(im.camera_id, "camera id"));
      out.put_name(im.name);
      out.put<uint64_t>(im.points2d.size());
      for (const ColmapPoint2D& p : im.points2d) {
        out.put<double>(p.xy.x());
        out.put<double>(p.xy.y());
        out.put<uint64_t>(p.point3d_id < 0 ? kNoPoint3DId : static_cast<uint64_t>(p.point3d_id));
      }
    }
    out.save(sparse_dir / "images.bin");
  }
  {
    BinaryWriter out;
    out.put<uint64_t>(model.points.size());
    for (const ColmapPoint3D& p : model.points) {
      LMB_CHECK(p.point3d_id >= 0, "write_colmap_binary: point3D id " << p.point3d_id << " is negative");
      out.put<uint64_t>(static_cast<uint64_t>(p.point3d_id));
      for (int k = 0; k < 3; ++k) out.put<double>(p.xyz[k]);
      for (int k = 0; k < 3; ++k) out.put<uint8_t>(p.rgb[k]);
      out.put<double>(p.error);
      out.put<uint64_t>(p.track.size());
      for (const ColmapTrackElement& e : p.track) {
        out.put<uint32_t>(checked_u32(e.image_id, "track image id"));
        out.put<uint32_t>(checked_u32(e.point2d_idx, "track point2D index"));
      }
    }
    out.save(sparse_dir / "points3D.bin");
  }
}

}  // namespace lmb
