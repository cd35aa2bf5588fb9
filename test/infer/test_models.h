// Hand-made inference models and frames for the infer tests.
//
// The "code model": class c has a 16-bit code (a distinct odd multiple hash of c). For each code
// bit j there are two stumps on descriptor bit j: one shared by the classes whose code bit is 1
// (+1 when the bit is set, -1 otherwise), one by the classes whose code bit is 0 (the reverse).
// A class therefore scores bias + (16 - 2 * hamming(descriptor bits 0..15, code)); with class
// biases 0 and the background's 14.5, only a keypoint whose low 16 descriptor bits equal a
// class's code is matched (to that class). Some stumps on context dims, shared by every class and
// the background with equal a and b, exercise the context path without changing the ranking.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/camera.h"
#include "common/random.h"
#include "common/rigid3.h"
#include "common/types.h"
#include "infer/bundle_index.h"
#include "infer/model.h"
#include "infer/walk_confidence.h"

namespace lmb::test {

constexpr int kCodeBits = 16;
constexpr int kCodeDescriptorBytes = 8;

inline uint32_t class_code(int32_t c) {
  return (static_cast<uint32_t>(c) * 40503u + 12345u) & 0xFFFFu;  // a bijection of 0..65535
}

inline ContextRegions test_regions() {
  return ContextRegions({{-4.f, -4.f, 4.f, 4.f}, {-1.f, 0.f, 3.f, 8.f}, {2.f, -6.f, 10.f, -1.f}});
}

inline Vocabulary test_vocabulary(uint64_t seed = 5) {
  Rng rng(seed);
  std::vector<uint8_t> words(4 * kCodeDescriptorBytes);
  for (auto& b : words) b = static_cast<uint8_t>(rng.below(256));
  return Vocabulary(kCodeDescriptorBytes, words);
}

inline void code_descriptor(int32_t c, Rng& rng, uint8_t* desc) {
  for (int i = 0; i < kCodeDescriptorBytes; ++i) desc[i] = static_cast<uint8_t>(rng.below(256));
  const uint32_t code = class_code(c);
  desc[0] = static_cast<uint8_t>(code & 0xFF);
  desc[1] = static_cast<uint8_t>(code >> 8);
}

// The code model with C classes at the given positions (C entries). Codes are distinct for the
// C used (checked by the caller's tests through matching).
inline ModelData make_code_model_data(const std::vector<Eigen::Vector3d>& positions, uint64_t seed = 1) {
  ModelData d;
  d.detector = "TEST";
  d.descriptor_bytes = kCodeDescriptorBytes;
  d.regions = test_regions();
  d.vocabulary = test_vocabulary();
  const int32_t C = static_cast<int32_t>(positions.size());
  d.num_classes = C;
  for (int32_t c = 0; c < C; ++c) d.class_landmark.push_back(1000 + 3 * c);
  d.class_position = positions;
  d.bias.assign(static_cast<size_t>(C) + 1, 0.0);
  d.bias[C] = 14.5;
  const int32_t context_dims = d.regions.size() * d.vocabulary.num_words();
  Rng rng(seed);
  std::vector<int32_t> everyone(static_cast<size_t>(C) + 1);
  for (int32_t c = 0; c <= C; ++c) everyone[c] = c;
  for (int j = 0; j < kCodeBits; ++j) {
    SharedStump one, zero;
    one.dim = zero.dim = context_dims + j;
    one.theta = zero.theta = 0;
    one.a = 2.0;
    one.b = -1.0;
    zero.a = -2.0;
    zero.b = 1.0;
    for (int32_t c = 0; c < C; ++c) ((class_code(c) >> j) & 1 ? one : zero).classes.push_back(c);
    if (!one.classes.empty()) d.stumps.push_back(one);
    if (!zero.classes.empty()) d.stumps.push_back(zero);
    // A context stump shared by everyone (a = 0: the same value above and below).
    SharedStump ctx;
    ctx.dim = static_cast<int32_t>(rng.below(static_cast<uint64_t>(context_dims)));
    ctx.theta = static_cast<uint8_t>(rng.below(200));
    ctx.a = 0.0;
    ctx.b = 0.25;
    ctx.classes = everyone;
    d.stumps.push_back(ctx);
  }
  d.inverted_file.assign(static_cast<size_t>(d.vocabulary.num_words()), {});
  // Every class in the list of the word its code descriptors quantize to (for the random upper
  // bytes used by code_descriptor, the word can vary: list the class under every word).
  for (int32_t w = 0; w < d.vocabulary.num_words(); ++w) {
    for (int32_t c = 0; c < C; ++c) d.inverted_file[w].push_back(c);
  }
  return d;
}

struct TestFrame {
  Camera camera;
  Rigid3d cam_from_world;
  Eigen::Vector3d gravity_in_cam;
  std::vector<Keypoint> keypoints;
  std::vector<uint8_t> descriptors;
  std::vector<int32_t> keypoint_class;  // true class or -1
};

inline Camera test_camera() {
  Camera camera;
  camera.model = CameraModel::kPinhole;
  camera.width = 640;
  camera.height = 480;
  camera.params = {500.0, 500.0, 320.0, 240.0};
  return camera;
}

// A world of num_classes landmarks seen by a known camera, and a frame observing num_inliers of
// them (exact pixels) plus num_outliers random keypoints.
struct TestWorld {
  std::vector<Eigen::Vector3d> positions;
  TestFrame frame;
};

inline TestWorld make_test_world(int32_t num_classes, int32_t num_inliers, int32_t num_outliers, uint64_t seed = 3) {
  TestWorld w;
  Rng rng(seed);
  TestFrame& f = w.frame;
  f.camera = test_camera();
  f.cam_from_world = Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 1, 0.3).normalized())),
                             Eigen::Vector3d(0.3, -0.2, 1.5));
  const Rigid3d world_from_cam = f.cam_from_world.inverse();
  f.gravity_in_cam = f.cam_from_world.rotation * Eigen::Vector3d(0, 0, -1);
  std::vector<Eigen::Vector2d> pixels;
  for (int32_t c = 0; c < num_classes; ++c) {
    const Eigen::Vector2d px(rng.uniform(20, 620), rng.uniform(20, 460));
    const double depth = rng.uniform(2.0, 8.0);
    w.positions.push_back(world_from_cam * (depth * f.camera.cam_from_img(px).homogeneous()));
    pixels.push_back(px);
  }
  for (int32_t i = 0; i < num_inliers + num_outliers; ++i) {
    Keypoint kp;
    std::vector<uint8_t> desc(kCodeDescriptorBytes);
    int32_t cls = -1;
    if (i < num_inliers) {
      cls = (i * 7) % num_classes;
      kp.x = static_cast<float>(pixels[cls].x());
      kp.y = static_cast<float>(pixels[cls].y());
      code_descriptor(cls, rng, desc.data());
    } else {
      kp.x = static_cast<float>(rng.uniform(0, 639));
      kp.y = static_cast<float>(rng.uniform(0, 479));
      for (auto& b : desc) b = static_cast<uint8_t>(rng.below(256));
    }
    kp.scale = static_cast<float>(rng.uniform(12, 40));
    kp.angle = static_cast<float>(rng.uniform(0, 360));
    f.keypoints.push_back(kp);
    f.descriptors.insert(f.descriptors.end(), desc.begin(), desc.end());
    f.keypoint_class.push_back(cls);
  }
  return w;
}

// `world`'s frame seen from its camera moved by `shift` (world frame): its first `inliers`
// landmark keypoints reprojected (those that stay in front of the camera and inside the image),
// then its other keypoints as they are.
inline TestFrame moved_frame(const TestWorld& world, const Eigen::Vector3d& shift, size_t inliers) {
  const TestFrame& f = world.frame;
  TestFrame out = f;
  out.cam_from_world =
      Rigid3d(f.cam_from_world.rotation, f.cam_from_world.translation - f.cam_from_world.rotation * shift);
  out.keypoints.clear();
  out.descriptors.clear();
  out.keypoint_class.clear();
  const size_t bytes = f.descriptors.size() / f.keypoints.size();
  size_t kept = 0;
  for (size_t k = 0; k < f.keypoints.size(); ++k) {
    Keypoint kp = f.keypoints[k];
    const int32_t c = f.keypoint_class[k];
    if (c >= 0) {
      Eigen::Vector2d px;
      if (kept == inliers || !out.camera.project(out.cam_from_world * world.positions[static_cast<size_t>(c)], &px) ||
          px.x() < 0 || px.y() < 0 || px.x() >= out.camera.width || px.y() >= out.camera.height) {
        continue;
      }
      kp.x = static_cast<float>(px.x());
      kp.y = static_cast<float>(px.y());
      ++kept;
    }
    out.keypoints.push_back(kp);
    out.descriptors.insert(out.descriptors.end(), f.descriptors.begin() + static_cast<std::ptrdiff_t>(k * bytes),
                           f.descriptors.begin() + static_cast<std::ptrdiff_t>((k + 1) * bytes));
    out.keypoint_class.push_back(c);
  }
  return out;
}

// The walk of the bundle walk tests, on make_test_world(101, 60, 140, 21): the first frame with
// every landmark keypoint, four 5 mm steps sideways with 30 of them, then a frame 1.5 m behind the
// camera with every one (a jump).
inline std::vector<TestFrame> walk_test_frames(const TestWorld& world) {
  const Eigen::Matrix3d world_from_cam = world.frame.cam_from_world.rotation.inverse().toRotationMatrix();
  std::vector<TestFrame> frames = {moved_frame(world, Eigen::Vector3d::Zero(), 60)};
  for (int i = 1; i <= 4; ++i) frames.push_back(moved_frame(world, 0.005 * i * world_from_cam.col(0), 30));
  frames.push_back(moved_frame(world, -1.5 * world_from_cam.col(2), 60));
  return frames;
}

// The frame rule of the walk tests: a pose explaining 60 keypoints is reported, one explaining 30
// is not.
inline PoseCalibration walk_test_frame_calibration() {
  PoseCalibration frame;
  frame.weights[0] = 10.0;  // log(1 + support)
  frame.bias = -10.0 * std::log(46.0);
  frame.threshold = 0.5;
  return frame;
}

// The walk rule of the walk tests: a step of a few millimetres a frame continues the walk, metres
// do not; poses agree within sqrt(2) x 1 cm + g x 1 cm.
inline WalkCalibration walk_test_walk_calibration() {
  WalkCalibration walk;
  walk.weights = {0.0, -5.0, 0.0, 0.0};
  walk.bias = 5.0;
  walk.threshold = 0.5;
  walk.translation_scale_m = 0.01;
  walk.rotation_scale_deg = 1.0;
  walk.agreement_noise_m = 0.01;
  walk.agreement_noise_deg = 0.5;
  walk.agreement_step_m = 0.01;
  walk.agreement_step_deg = 1.0;
  return walk;
}

// The map fingerprint the tests' bundle indexes record (their models come from no map file).
constexpr uint64_t kTestMapFingerprint = 0x5eed0f0e5eed0f0eull;

// Writes a bundle index (version 3) of `areas` (entries of describe_area) for the test map.
inline void write_test_bundle(const std::filesystem::path& path, double reach, const std::vector<BundleArea>& areas,
                              const PoseCalibration* calibration = nullptr) {
  BundleIndex index;
  index.reach = reach;
  index.map_fingerprint = kTestMapFingerprint;
  index.areas = areas;
  if (calibration != nullptr) index.calibration = *calibration;
  write_bundle_index(path, index);
}

}  // namespace lmb::test
