// A localization case that one architecture writes and another replays (test/infer/cross_arch):
// a model file, the query frames of a map as plain binary (no HDF5: the inference library's tests
// read it on any architecture), and the transcript of localizing them with fixed options.
//
// frames.bin (little-endian): "LMBCASE1", uint32 descriptor_bytes, uint32 number of frames; each
// frame: uint32 name length + name bytes, int32 camera model id, int32 width, int32 height,
// uint32 number of params + that many doubles, 3 doubles gravity_in_cam, uint32 n, n keypoints
// (x, y, scale, angle as 4 floats), n * descriptor_bytes descriptor bytes.
//
// The transcript, per frame and setting (case_settings()): the frame's matches (keypoint, rank,
// class, landmark, score and background score as hexadecimal floats: every bit), the pose's
// success, inlier count and inlier mask, and cam_from_world (rotation as a quaternion w x y z,
// translation) as hexadecimal floats.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/error.h"
#include "common/types.h"
#include "infer/localizer.h"

namespace lmb::test {

struct CaseFrame {
  std::string name;
  Camera camera;
  Eigen::Vector3d gravity_in_cam = Eigen::Vector3d(0, 1, 0);
  std::vector<Keypoint> keypoints;
  std::vector<uint8_t> descriptors;
};

namespace detail_case {
template <class T>
void put(std::ostream& out, const T& v) {
  static_assert(std::is_trivially_copyable_v<T>);
  out.write(reinterpret_cast<const char*>(&v), sizeof(T));
}
template <class T>
T get(std::istream& in, const std::string& path) {
  T v;
  in.read(reinterpret_cast<char*>(&v), sizeof(T));
  LMB_CHECK(in.gcount() == static_cast<std::streamsize>(sizeof(T)), path << ": truncated");
  return v;
}
}  // namespace detail_case

inline void write_case_frames(const std::string& path, const std::vector<CaseFrame>& frames,
                              uint32_t descriptor_bytes) {
  using detail_case::put;
  std::ofstream out(path, std::ios::binary);
  LMB_CHECK(out.good(), path << ": cannot write");
  out.write("LMBCASE1", 8);
  put(out, descriptor_bytes);
  put(out, static_cast<uint32_t>(frames.size()));
  for (const CaseFrame& f : frames) {
    put(out, static_cast<uint32_t>(f.name.size()));
    out.write(f.name.data(), static_cast<std::streamsize>(f.name.size()));
    put(out, static_cast<int32_t>(f.camera.model));
    put(out, static_cast<int32_t>(f.camera.width));
    put(out, static_cast<int32_t>(f.camera.height));
    put(out, static_cast<uint32_t>(f.camera.params.size()));
    for (double p : f.camera.params) put(out, p);
    for (int i = 0; i < 3; ++i) put(out, f.gravity_in_cam[i]);
    put(out, static_cast<uint32_t>(f.keypoints.size()));
    for (const Keypoint& k : f.keypoints) {
      put(out, k.x);
      put(out, k.y);
      put(out, k.scale);
      put(out, k.angle);
    }
    out.write(reinterpret_cast<const char*>(f.descriptors.data()), static_cast<std::streamsize>(f.descriptors.size()));
  }
  LMB_CHECK(out.good(), path << ": write failed");
}

inline std::vector<CaseFrame> read_case_frames(const std::string& path, uint32_t* descriptor_bytes) {
  using detail_case::get;
  std::ifstream in(path, std::ios::binary);
  LMB_CHECK(in.good(), path << ": cannot open");
  char magic[8];
  in.read(magic, 8);
  LMB_CHECK(in.gcount() == 8 && std::memcmp(magic, "LMBCASE1", 8) == 0, path << ": not a case frames file");
  *descriptor_bytes = get<uint32_t>(in, path);
  const uint32_t count = get<uint32_t>(in, path);
  LMB_CHECK(count < 100000 && *descriptor_bytes <= 1024, path << ": implausible header");
  std::vector<CaseFrame> frames(count);
  for (CaseFrame& f : frames) {
    const uint32_t name_size = get<uint32_t>(in, path);
    LMB_CHECK(name_size < 4096, path << ": implausible name length");
    f.name.resize(name_size);
    in.read(f.name.data(), name_size);
    f.camera.model = static_cast<CameraModel>(get<int32_t>(in, path));
    f.camera.width = get<int32_t>(in, path);
    f.camera.height = get<int32_t>(in, path);
    const uint32_t num_params = get<uint32_t>(in, path);
    LMB_CHECK(num_params <= 16, path << ": implausible camera");
    for (uint32_t i = 0; i < num_params; ++i) f.camera.params.push_back(get<double>(in, path));
    for (int i = 0; i < 3; ++i) f.gravity_in_cam[i] = get<double>(in, path);
    const uint32_t n = get<uint32_t>(in, path);
    LMB_CHECK(n <= 65535, path << ": implausible keypoint count");
    f.keypoints.resize(n);
    for (Keypoint& k : f.keypoints) {
      k.x = get<float>(in, path);
      k.y = get<float>(in, path);
      k.scale = get<float>(in, path);
      k.angle = get<float>(in, path);
    }
    f.descriptors.resize(static_cast<size_t>(n) * *descriptor_bytes);
    in.read(reinterpret_cast<char*>(f.descriptors.data()), static_cast<std::streamsize>(f.descriptors.size()));
    LMB_CHECK(in.gcount() == static_cast<std::streamsize>(f.descriptors.size()), path << ": truncated");
  }
  return frames;
}

// The settings every frame is localized with: background rejection with the inverted file, and
// (as a briefly trained model needs) no rejection with the 100 best margins, 3 matches a keypoint
// and 2,000 RANSAC iterations.
inline std::vector<std::pair<std::string, LocalizerOptions>> case_settings() {
  LocalizerOptions a;
  a.classifier.use_inverted_file = true;
  a.pose.seed = 1;
  LocalizerOptions b;
  b.classifier.top_k = 3;
  b.classifier.min_margin = -std::numeric_limits<double>::infinity();
  b.max_correspondences = 100;
  b.pose.max_iterations = 2000;
  b.pose.seed = 1;
  return {{"inverted-margin0", a}, {"dense-best100", b}};
}

inline std::string hex(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%a", v);
  return buf;
}

// The transcript lines of one frame and setting (see the file comment).
inline std::string transcript(const std::string& frame, const std::string& setting, const LocalizeResult& r) {
  std::ostringstream out;
  out << "frame " << frame << " setting " << setting << " keypoints " << r.matches.num_keypoints() << " matches "
      << r.matches.matches.size() << "\n";
  for (int32_t k = 0; k < r.matches.num_keypoints(); ++k) {
    for (int32_t j = 0; j < r.matches.count(k); ++j) {
      const ClassMatch& m = r.matches.of(k)[j];
      out << "match " << k << " " << j << " " << m.cls << " " << m.landmark << " " << hex(m.score) << " "
          << hex(m.background_score) << "\n";
    }
  }
  out << "pose success " << (r.pose.success ? 1 : 0) << " inliers " << r.pose.num_inliers << " correspondences "
      << r.correspondence_keypoint.size() << "\n";
  out << "inlier_mask ";
  for (size_t i = 0; i < r.pose.inlier_mask.size(); ++i) out << (r.pose.inlier_mask[i] ? '1' : '0');
  out << "\n";
  const Eigen::Quaterniond& q = r.pose.cam_from_world.rotation;
  const Eigen::Vector3d& t = r.pose.cam_from_world.translation;
  out << "cam_from_world " << hex(q.w()) << " " << hex(q.x()) << " " << hex(q.y()) << " " << hex(q.z()) << " "
      << hex(t.x()) << " " << hex(t.y()) << " " << hex(t.z()) << "\n";
  return out.str();
}

}  // namespace lmb::test
