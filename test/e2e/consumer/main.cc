// A tiny application using the installed LandmarkBoost inference library. Each check_* function
// exercises one public API and returns the number of failures; main returns nonzero when any
// check fails. Later APIs (the localizer, the C API) get their own check_* function here.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "common/camera.h"
#include "common/error.h"
#include "common/random.h"
#include "infer/c_api.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "infer/pose_estimator.h"

// c_check.c: the same localization through the C API, from C.
extern "C" int lmb_consumer_c_localize(const char* model_path, const lmb_camera* camera, const lmb_keypoint* keypoints,
                                       int n, const uint8_t* descriptors, const double gravity[3], lmb_pose* pose);

namespace {

int failures = 0;

void expect(bool ok, const char* what) {
  std::printf("%s: %s\n", ok ? "ok  " : "FAIL", what);
  if (!ok) ++failures;
}

lmb::Camera make_camera() {
  lmb::Camera camera;
  camera.model = lmb::CameraModel::kSimpleRadial;
  camera.width = 640;
  camera.height = 480;
  camera.params = {500.0, 320.0, 240.0, -0.1};
  camera.check();  // from the installed static LandmarkBoost::common
  return camera;
}

// 100 points seen by a known camera, 30 of them with a wrong pixel; returns the true pose.
lmb::Rigid3d make_problem(const lmb::Camera& camera, std::vector<Eigen::Vector2d>* pixels,
                          std::vector<Eigen::Vector3d>* points_world) {
  lmb::Rng rng(2024);
  const lmb::Rigid3d cam_from_world(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())),
                                    Eigen::Vector3d(0.5, -1.0, 2.0));
  const lmb::Rigid3d world_from_cam = cam_from_world.inverse();
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector2d pixel(rng.uniform(0, camera.width), rng.uniform(0, camera.height));
    const double depth = rng.uniform(2.0, 10.0);
    points_world->push_back(world_from_cam * (depth * camera.cam_from_img(pixel).homogeneous()));
    pixels->push_back(i < 30 ? Eigen::Vector2d(rng.uniform(0, camera.width), rng.uniform(0, camera.height)) : pixel);
  }
  return cam_from_world;
}

void check_pose_api() {
  const lmb::Camera camera = make_camera();
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points_world;
  const lmb::Rigid3d truth = make_problem(camera, &pixels, &points_world);

  lmb::PoseEstimatorOptions options;
  options.seed = 7;
  const lmb::PoseResult result = lmb::estimate_absolute_pose(camera, pixels, points_world, options);
  expect(result.success, "estimate_absolute_pose succeeds");
  expect(lmb::position_error(result.cam_from_world, truth) < 1e-3, "position within 1 mm");
  expect(lmb::rotation_error_deg(result.cam_from_world, truth) < 0.01, "rotation within 0.01 deg");
  expect(result.num_inliers >= 70 && result.num_inliers <= 72, "70 inliers (+ chance outliers)");
  std::printf("      position error %.2e m, %d inliers, %d iterations\n",
              lmb::position_error(result.cam_from_world, truth), result.num_inliers, result.stats.iterations);

  // An lmb::Error thrown inside liblmb_infer.so is caught here by type.
  bool caught = false;
  try {
    points_world.pop_back();
    lmb::estimate_absolute_pose(camera, pixels, points_world, options);
  } catch (const lmb::Error& e) {
    caught = true;
    std::printf("      caught lmb::Error: %s\n", e.what());
  }
  expect(caught, "lmb::Error crosses the library boundary");
}

// A hand-made model, as an app's test would build one: 80 landmark classes recognised by a 16-bit
// code in the first two descriptor bytes (two stumps per code bit), a background that beats any
// class with a wrong bit, and one context stump. Returns the model and a frame of 50 keypoints on
// landmarks plus 50 random ones, seen from cam_from_world.
struct ModelAndFrame {
  lmb::ModelData data;
  lmb::Rigid3d cam_from_world;
  std::vector<lmb::Keypoint> keypoints;
  std::vector<uint8_t> descriptors;
  Eigen::Vector3d gravity_in_cam;
};

uint32_t code_of(int c) { return (static_cast<uint32_t>(c) * 40503u + 777u) & 0xFFFFu; }

ModelAndFrame make_model_and_frame(const lmb::Camera& camera) {
  ModelAndFrame r;
  lmb::Rng rng(77);
  r.cam_from_world =
      lmb::Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(-0.2, Eigen::Vector3d(0.3, 1, 0.1).normalized())),
                   Eigen::Vector3d(-0.4, 0.1, 1.0));
  r.gravity_in_cam = r.cam_from_world.rotation * Eigen::Vector3d(0, 0, -1);
  lmb::ModelData& d = r.data;
  d.detector = "BRISK";
  d.descriptor_bytes = 64;
  d.regions = lmb::ContextRegions(lmb::ContextRegionOptions{});
  std::vector<uint8_t> words(8 * 64);
  for (auto& b : words) b = static_cast<uint8_t>(rng.below(256));
  d.vocabulary = lmb::Vocabulary(64, words);
  const int C = 80;
  d.num_classes = C;
  const lmb::Rigid3d world_from_cam = r.cam_from_world.inverse();
  std::vector<Eigen::Vector2d> pixels;
  for (int c = 0; c < C; ++c) {
    const Eigen::Vector2d px(rng.uniform(10, camera.width - 10), rng.uniform(10, camera.height - 10));
    d.class_landmark.push_back(500 + c);
    d.class_position.push_back(world_from_cam * (rng.uniform(2, 9) * camera.cam_from_img(px).homogeneous()));
    pixels.push_back(px);
  }
  d.bias.assign(C + 1, 0.0);
  d.bias[C] = 14.5;
  const int context_dims = d.regions.size() * d.vocabulary.num_words();
  for (int j = 0; j < 16; ++j) {
    lmb::SharedStump one, zero;
    one.dim = zero.dim = context_dims + j;
    one.a = 2.0;
    one.b = -1.0;
    zero.a = -2.0;
    zero.b = 1.0;
    for (int c = 0; c < C; ++c) ((code_of(c) >> j) & 1 ? one : zero).classes.push_back(c);
    d.stumps.push_back(one);
    d.stumps.push_back(zero);
  }
  lmb::SharedStump context;
  context.dim = 123;
  context.theta = 10;
  context.a = 0.0;
  context.b = 0.5;
  for (int c = 0; c <= C; ++c) context.classes.push_back(c);
  d.stumps.push_back(context);
  d.inverted_file.assign(8, {});
  for (auto& list : d.inverted_file) {
    for (int c = 0; c < C; ++c) list.push_back(c);
  }
  for (int i = 0; i < 100; ++i) {
    lmb::Keypoint kp;
    std::vector<uint8_t> desc(64);
    for (auto& b : desc) b = static_cast<uint8_t>(rng.below(256));
    if (i < 50) {
      const int c = i;
      kp.x = static_cast<float>(pixels[c].x());  // COLMAP pixel convention (common/types.h)
      kp.y = static_cast<float>(pixels[c].y());
      desc[0] = static_cast<uint8_t>(code_of(c) & 0xFF);
      desc[1] = static_cast<uint8_t>(code_of(c) >> 8);
    } else {
      kp.x = static_cast<float>(rng.uniform(0, camera.width - 1));
      kp.y = static_cast<float>(rng.uniform(0, camera.height - 1));
    }
    kp.scale = static_cast<float>(rng.uniform(12, 30));
    r.keypoints.push_back(kp);
    r.descriptors.insert(r.descriptors.end(), desc.begin(), desc.end());
  }
  return r;
}

std::string model_path() { return (std::filesystem::temp_directory_path() / "lmb_consumer_model.lbm").string(); }

void check_localizer_api() {
  const lmb::Camera camera = make_camera();
  const ModelAndFrame mf = make_model_and_frame(camera);
  lmb::Model(mf.data).save(model_path());
  const std::shared_ptr<const lmb::Model> model = lmb::Model::load(model_path());
  expect(model->num_classes() == 80, "Model::load reads the model");
  lmb::LocalizerOptions options;
  options.classifier.use_inverted_file = true;
  const lmb::Localizer localizer(model, options);
  const lmb::LocalizeResult r = localizer.localize(camera, mf.keypoints, mf.descriptors.data(), mf.gravity_in_cam);
  int correct = 0;
  for (int k = 0; k < 50; ++k) correct += r.matches.count(k) == 1 && r.matches.of(k)[0].landmark == 500 + k;
  expect(correct == 50, "Localizer matches the 50 landmark keypoints");
  expect(r.pose.success, "Localizer finds the pose");
  expect(lmb::position_error(r.pose.cam_from_world, mf.cam_from_world) < 1e-3, "Localizer position within 1 mm");
  std::printf("      C++: %d correct matches, %d inliers, %.1f ms\n", correct, r.pose.num_inliers, r.timings.total_ms);
  bool caught = false;
  try {
    std::vector<uint8_t> bytes = model->to_bytes();
    bytes[30] ^= 1;
    lmb::Model::from_bytes(bytes.data(), bytes.size(), "damaged");
  } catch (const lmb::Error& e) {
    caught = true;
  }
  expect(caught, "a damaged model is rejected with lmb::Error");
}

void check_c_api() {
  const lmb::Camera camera = make_camera();
  const ModelAndFrame mf = make_model_and_frame(camera);
  lmb::Model(mf.data).save(model_path());
  std::vector<lmb_keypoint> keypoints;
  for (const lmb::Keypoint& k : mf.keypoints) keypoints.push_back({k.x, k.y, k.scale, k.angle});
  const lmb_camera c_camera{LMB_CAMERA_SIMPLE_RADIAL, camera.width, camera.height, camera.params.data(),
                            static_cast<int>(camera.params.size())};
  const double gravity[3] = {mf.gravity_in_cam.x(), mf.gravity_in_cam.y(), mf.gravity_in_cam.z()};
  lmb_pose pose;
  const int rc = lmb_consumer_c_localize(model_path().c_str(), &c_camera, keypoints.data(),
                                         static_cast<int>(keypoints.size()), mf.descriptors.data(), gravity, &pose);
  expect(rc == 0, "C API: load and localize");
  expect(pose.success == 1, "C API: pose found");
  const lmb::Rigid3d got(Eigen::Quaterniond(pose.rotation[0], pose.rotation[1], pose.rotation[2], pose.rotation[3]),
                         Eigen::Vector3d(pose.translation[0], pose.translation[1], pose.translation[2]));
  expect(lmb::position_error(got, mf.cam_from_world) < 1e-3, "C API: position within 1 mm");
  expect(lmb::rotation_error_deg(got, mf.cam_from_world) < 0.01, "C API: rotation within 0.01 deg");
  std::filesystem::remove(model_path());
}

}  // namespace

int main() {
  check_pose_api();
  check_localizer_api();
  check_c_api();
  std::printf("%s\n", failures == 0 ? "consumer: all checks passed" : "consumer: FAILED");
  return failures == 0 ? 0 : 1;
}
