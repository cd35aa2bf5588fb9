#include "common/io/colmap_binary.h"

#include <unistd.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

std::vector<char> read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_bytes(const fs::path& path, const std::vector<char>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// Little-endian appends, independent of the code under test, following COLMAP's documented layout.
struct Bytes {
  std::vector<char> data;
  template <typename T>
  Bytes& put(T v) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (size_t i = 0; i < sizeof(T); ++i) data.push_back(static_cast<char>(b[i]));  // x86: little-endian
    return *this;
  }
  Bytes& name(const std::string& s) {
    data.insert(data.end(), s.begin(), s.end());
    data.push_back('\0');
    return *this;
  }
};

// A model using every supported camera model, 2D points and tracks.
ColmapModel sample_model() {
  ColmapModel m;
  const std::vector<std::pair<CameraModel, std::vector<double>>> cams = {
      {CameraModel::kSimplePinhole, {500, 320, 240}},
      {CameraModel::kPinhole, {510, 490, 318, 241}},
      {CameraModel::kSimpleRadial, {500, 320, 240, -0.08}},
      {CameraModel::kRadial, {500, 320, 240, -0.1, 0.02}},
      {CameraModel::kOpenCV, {510, 490, 318, 241, -0.2, 0.05, 0.001, -0.002}},
      {CameraModel::kFullOpenCV, {517.3, 516.5, 318.6, 255.3, 0.2624, -0.9531, -0.0054, 0.0026, 1.1633, 0, 0, 0}},
  };
  for (size_t k = 0; k < cams.size(); ++k) {
    Camera c;
    c.model = cams[k].first;
    c.width = 640 + static_cast<int>(k);
    c.height = 480;
    c.params = cams[k].second;
    m.cameras[static_cast<int>(10 + k)] = c;
  }
  for (int i = 0; i < 6; ++i) {
    ColmapImage im;
    im.image_id = 100 - i;
    im.camera_id = 10 + i;
    im.name = "seq/frame_" + std::to_string(i) + ".jpg";
    im.cam_from_world.rotation =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.37 * i + 0.1, Eigen::Vector3d(0.2, 1, 0.1 * i).normalized()));
    im.cam_from_world.translation = Eigen::Vector3d(i * 0.1, -2.0 * i, 0.5 + 1.0 / 3.0);
    for (int k = 0; k < i; ++k) {
      ColmapPoint2D p;
      p.xy = Eigen::Vector2d(10.25 * k + 0.1, 7.5 * k + 1.0 / 7.0);
      p.point3d_id = k % 2 ? ColmapPoint2D::kNoPoint3D : 1000 + k;
      im.points2d.push_back(p);
    }
    m.images.push_back(im);
  }
  std::sort(m.images.begin(), m.images.end(),
            [](const ColmapImage& a, const ColmapImage& b) { return a.image_id < b.image_id; });
  for (int k = 0; k < 3; ++k) {
    ColmapPoint3D p;
    p.point3d_id = 1000 + 2 * k;
    p.xyz = Eigen::Vector3d(k, 1.0 / (k + 3), -k * 0.7);
    p.rgb = Eigen::Matrix<uint8_t, 3, 1>(static_cast<uint8_t>(k), 200, 255);
    p.error = 0.25 * k;
    p.track = {{100 - 5, 2 * k}, {100 - 4, 0}};
    m.points.push_back(p);
  }
  return m;
}

// Models read from files compare exactly; `a` straight from memory may differ from what was read by
// the last-bit renormalization of its quaternions (checked_rotation divides by the norm).
void expect_same(const ColmapModel& a, const ColmapModel& b, bool exact = true) {
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (const auto& [id, ca] : a.cameras) {
    ASSERT_TRUE(b.cameras.count(id)) << id;
    const Camera& cb = b.cameras.at(id);
    EXPECT_EQ(ca.model, cb.model);
    EXPECT_EQ(ca.width, cb.width);
    EXPECT_EQ(ca.height, cb.height);
    EXPECT_EQ(ca.params, cb.params);
  }
  ASSERT_EQ(a.images.size(), b.images.size());
  for (size_t i = 0; i < a.images.size(); ++i) {
    const ColmapImage& x = a.images[i];
    const ColmapImage& y = b.images[i];
    EXPECT_EQ(x.image_id, y.image_id);
    EXPECT_EQ(x.camera_id, y.camera_id);
    EXPECT_EQ(x.name, y.name);
    if (exact) {
      EXPECT_EQ(x.cam_from_world.rotation.coeffs(), y.cam_from_world.rotation.coeffs());
    } else {
      EXPECT_LT((x.cam_from_world.rotation.coeffs() - y.cam_from_world.rotation.coeffs()).norm(), 1e-15);
    }
    EXPECT_EQ(x.cam_from_world.translation, y.cam_from_world.translation);
    EXPECT_EQ(x.points2d, y.points2d);
  }
  ASSERT_EQ(a.points.size(), b.points.size());
  for (size_t i = 0; i < a.points.size(); ++i) {
    EXPECT_EQ(a.points[i].point3d_id, b.points[i].point3d_id);
    EXPECT_EQ(a.points[i].xyz, b.points[i].xyz);
    EXPECT_EQ(a.points[i].rgb, b.points[i].rgb);
    EXPECT_EQ(a.points[i].error, b.points[i].error);
    EXPECT_EQ(a.points[i].track, b.points[i].track);
  }
}

class ColmapBinaryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_colmap_bin_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Reads the binary model in dir_ and returns the error message ("" if none).
  std::string read_error() {
    try {
      read_colmap_binary(dir_);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }

  void expect_error(const std::string& needle) {
    const std::string message = read_error();
    EXPECT_NE(message.find(needle), std::string::npos) << "message: '" << message << "', expected: " << needle;
    EXPECT_EQ(message.find('\n'), std::string::npos) << "not one line: " << message;
  }

  fs::path dir_;
};

TEST_F(ColmapBinaryTest, TextAndBinaryOfTheSameModelReadIdentically) {
  const ColmapModel m = sample_model();
  write_colmap_text(m, dir_ / "text");
  write_colmap_binary(m, dir_ / "bin");
  const ColmapModel from_text = read_colmap_text(dir_ / "text");
  const ColmapModel from_bin = read_colmap_binary(dir_ / "bin");
  expect_same(from_text, from_bin);
  expect_same(m, from_bin, /*exact=*/false);
  // The auto-detecting reader picks the right one.
  ColmapFormat format = ColmapFormat::kText;
  expect_same(read_colmap_model(dir_ / "bin", &format), from_text);
  EXPECT_EQ(format, ColmapFormat::kBinary);
  expect_same(read_colmap_model(dir_ / "text", &format), from_bin);
  EXPECT_EQ(format, ColmapFormat::kText);
}

TEST_F(ColmapBinaryTest, WriterFollowsColmapByteLayout) {
  ColmapModel m;
  Camera c;
  c.model = CameraModel::kPinhole;
  c.width = 640;
  c.height = 480;
  c.params = {500, 501, 320, 240};
  m.cameras[7] = c;
  ColmapImage im;
  im.image_id = 3;
  im.camera_id = 7;
  im.name = "a/b.png";
  im.cam_from_world.translation = Eigen::Vector3d(1, 2, 3);
  im.points2d = {{Eigen::Vector2d(1.5, 2.5), ColmapPoint2D::kNoPoint3D}, {Eigen::Vector2d(3.5, 4.5), 9}};
  m.images.push_back(im);
  ColmapPoint3D p;
  p.point3d_id = 9;
  p.xyz = Eigen::Vector3d(4, 5, 6);
  p.rgb = Eigen::Matrix<uint8_t, 3, 1>(1, 2, 3);
  p.error = 0.5;
  p.track = {{3, 1}};
  m.points.push_back(p);
  write_colmap_binary(m, dir_);

  Bytes cameras;
  cameras.put<uint64_t>(1).put<uint32_t>(7).put<int32_t>(1).put<uint64_t>(640).put<uint64_t>(480);
  for (double v : {500.0, 501.0, 320.0, 240.0}) cameras.put<double>(v);
  EXPECT_EQ(read_bytes(dir_ / "cameras.bin"), cameras.data);

  Bytes images;
  images.put<uint64_t>(1).put<uint32_t>(3);
  for (double v : {1.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0}) images.put<double>(v);  // qw qx qy qz tx ty tz
  images.put<uint32_t>(7).name("a/b.png").put<uint64_t>(2);
  images.put<double>(1.5).put<double>(2.5).put<uint64_t>(std::numeric_limits<uint64_t>::max());
  images.put<double>(3.5).put<double>(4.5).put<uint64_t>(9);
  EXPECT_EQ(read_bytes(dir_ / "images.bin"), images.data);

  Bytes points;
  points.put<uint64_t>(1).put<uint64_t>(9).put<double>(4).put<double>(5).put<double>(6);
  points.put<uint8_t>(1).put<uint8_t>(2).put<uint8_t>(3).put<double>(0.5).put<uint64_t>(1);
  points.put<uint32_t>(3).put<uint32_t>(1);
  EXPECT_EQ(read_bytes(dir_ / "points3D.bin"), points.data);

  const ColmapModel r = read_colmap_binary(dir_);
  expect_same(m, r, /*exact=*/false);
  EXPECT_EQ(r.images[0].points2d[0].point3d_id, ColmapPoint2D::kNoPoint3D);
}

TEST_F(ColmapBinaryTest, TruncationAtEveryOffsetFailsNamingFileAndRecord) {
  const ColmapModel m = sample_model();
  for (const char* file : {"cameras.bin", "images.bin", "points3D.bin"}) {
    write_colmap_binary(m, dir_);
    const std::vector<char> full = read_bytes(dir_ / file);
    ASSERT_GT(full.size(), 100u);
    int failures = 0;
    for (size_t size = 0; size < full.size(); ++size) {
      write_bytes(dir_ / file, std::vector<char>(full.begin(), full.begin() + static_cast<long>(size)));
      const std::string message = read_error();
      ASSERT_FALSE(message.empty()) << file << " truncated to " << size << " bytes was accepted";
      EXPECT_NE(message.find(file), std::string::npos) << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
      // Truncations inside a record say "truncated" or name a count that exceeds the bytes left.
      EXPECT_TRUE(message.find("truncated") != std::string::npos || message.find("bytes are left") != std::string::npos)
          << message;
      ++failures;
    }
    EXPECT_EQ(failures, static_cast<int>(full.size()));
  }
  // Named examples: cameras.bin cut inside the last camera's parameters; images.bin cut inside
  // the last image's name.
  write_colmap_binary(m, dir_);
  std::vector<char> cameras = read_bytes(dir_ / "cameras.bin");
  cameras.resize(cameras.size() - 3);
  write_bytes(dir_ / "cameras.bin", cameras);
  expect_error(
      "cameras.bin: camera record 5 (id 15): truncated file: cannot read camera parameter (8 bytes needed, 5 left)");
  write_colmap_binary(m, dir_);
  std::vector<char> images = read_bytes(dir_ / "images.bin");
  images.resize(images.size() - 8 - 3);  // the last image (id 100) has no 2D points: count, NUL, 2 chars
  write_bytes(dir_ / "images.bin", images);
  expect_error("images.bin: image record 5 (id 100): truncated file: image name has no NUL terminator");
}

TEST_F(ColmapBinaryTest, WrongCountsFailBeforeAllocating) {
  const ColmapModel m = sample_model();
  write_colmap_binary(m, dir_);
  const std::vector<char> images = read_bytes(dir_ / "images.bin");
  auto with_count = [&](uint64_t count) {
    std::vector<char> b = images;
    std::memcpy(b.data(), &count, 8);
    write_bytes(dir_ / "images.bin", b);
  };
  with_count(uint64_t{1} << 60);  // would be exabytes if trusted
  expect_error("images.bin: number of images is 1152921504606846976 but only");
  with_count(m.images.size() - 1);
  expect_error("images.bin: ");
  expect_error("trailing bytes after the last record");
  with_count(m.images.size() + 1);
  expect_error("images.bin: image record 6");
  write_bytes(dir_ / "images.bin", images);

  // A 2D point count that exceeds the file.
  std::vector<char> points = read_bytes(dir_ / "points3D.bin");
  const uint64_t huge = std::numeric_limits<uint64_t>::max() / 2;
  // The first point's track length sits after id (8), xyz (24), rgb (3), error (8), past the count (8).
  std::memcpy(points.data() + 8 + 8 + 24 + 3 + 8, &huge, 8);
  write_bytes(dir_ / "points3D.bin", points);
  expect_error("points3D.bin: point3D record 0 (id 1000): track length is 9223372036854775807 but only");
}

TEST_F(ColmapBinaryTest, UnsupportedAndUnknownCameraModelIds) {
  const ColmapModel m = sample_model();
  write_colmap_binary(m, dir_);
  const std::vector<char> cameras = read_bytes(dir_ / "cameras.bin");
  const std::vector<std::pair<int32_t, std::string>> cases = {
      {5, "unsupported camera model id 5 (OPENCV_FISHEYE)"},
      {7, "unsupported camera model id 7 (FOV)"},
      {8, "unsupported camera model id 8 (SIMPLE_RADIAL_FISHEYE)"},
      {9, "unsupported camera model id 9 (RADIAL_FISHEYE)"},
      {10, "unsupported camera model id 10 (THIN_PRISM_FISHEYE)"},
      {42, "unknown camera model id 42"},
      {-1, "unknown camera model id -1"},
  };
  for (const auto& [id, needle] : cases) {
    std::vector<char> b = cameras;
    std::memcpy(b.data() + 8 + 4, &id, 4);  // the first camera's model id
    write_bytes(dir_ / "cameras.bin", b);
    expect_error("cameras.bin: camera record 0 (id 10): " + needle);
  }
}

TEST_F(ColmapBinaryTest, BadValuesFailWithOneClearLine) {
  ColmapModel m = sample_model();
  m.images[0].cam_from_world.rotation.coeffs() *= 1.2;  // norm 1.2
  write_colmap_binary(m, dir_);
  expect_error("images.bin: image record 0 (id 95): quaternion is not a rotation (norm 1.2");

  m = sample_model();
  m.images[2].cam_from_world.translation.y() = std::nan("");
  write_colmap_binary(m, dir_);
  expect_error("images.bin: image record 2 (id 97): translation component is not finite");

  m = sample_model();
  m.cameras.at(12).params[0] = std::numeric_limits<double>::infinity();
  write_colmap_binary(m, dir_);
  expect_error("cameras.bin: camera record 2 (id 12): camera parameter is not finite");

  m = sample_model();
  m.cameras.at(11).params[0] = -5;
  write_colmap_binary(m, dir_);
  expect_error("cameras.bin: camera record 1 (id 11): focal length must be positive");

  m = sample_model();
  m.images[1].camera_id = 99;
  write_colmap_binary(m, dir_);
  expect_error("images.bin: image record 1 (id 96): image refers to camera 99, which cameras.bin lacks");

  m = sample_model();
  m.images[3].name = m.images[1].name;
  write_colmap_binary(m, dir_);
  expect_error("images.bin: image record 3 (id 98): duplicate image name seq/frame_4.jpg");

  m = sample_model();
  m.points[1].xyz.z() = std::nan("");
  write_colmap_binary(m, dir_);
  expect_error("points3D.bin: point3D record 1 (id 1002): coordinate is not finite");

  m = sample_model();
  m.images[4].points2d[0].xy.x() = std::nan("");
  write_colmap_binary(m, dir_);
  expect_error("images.bin: image record 4 (id 99): 2D point x is not finite");

  m = sample_model();
  m.images[2].name = "seq/../../../escape.jpg";  // names must stay inside the image folder
  write_colmap_binary(m, dir_);
  expect_error("images.bin: image record 2 (id 97): image name 'seq/../../../escape.jpg' leaves the image folder");

  fs::remove(dir_ / "images.bin");
  expect_error("images.bin: cannot open file: No such file or directory");
}

}  // namespace
}  // namespace lmb
