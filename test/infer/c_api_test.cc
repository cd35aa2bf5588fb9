// The C API: same answers as the C++ API, status codes and last-error text, no exception escapes.
#include "infer/c_api.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "infer/bundle_localizer.h"
#include "infer/localizer.h"
#include "infer/version.h"
#include "infer/walk_confidence.h"
#include "test/infer/test_models.h"

namespace lmb {
namespace {

struct CFixture {
  test::TestWorld world = test::make_test_world(101, 60, 140, 21);
  Model model{test::make_code_model_data(world.positions)};
  std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("lmb_c_api_test_" + std::to_string(::getpid()) + ".lbm");
  std::vector<lmb_keypoint> keypoints;
  lmb_camera camera{};

  CFixture() {
    model.save(path);
    for (const Keypoint& k : world.frame.keypoints) keypoints.push_back({k.x, k.y, k.scale, k.angle});
    camera.model = LMB_CAMERA_PINHOLE;
    camera.width = world.frame.camera.width;
    camera.height = world.frame.camera.height;
    camera.params = world.frame.camera.params.data();
    camera.num_params = static_cast<int>(world.frame.camera.params.size());
  }
  ~CFixture() { std::filesystem::remove(path); }
};

TEST(CApiTest, LocalizesLikeTheCppApi) {
  CFixture fx;
  lmb_model* model = nullptr;
  ASSERT_EQ(lmb_model_load(fx.path.c_str(), &model), LMB_OK) << lmb_last_error();
  EXPECT_EQ(lmb_model_descriptor_bytes(model), test::kCodeDescriptorBytes);
  EXPECT_EQ(lmb_model_num_classes(model), 101);
  lmb_localize_options options;
  lmb_localize_options_init(&options);
  options.top_k = 2;
  options.seed = 5;
  const Eigen::Vector3d& g = fx.world.frame.gravity_in_cam;
  const double gravity[3] = {g.x(), g.y(), g.z()};
  lmb_pose pose;
  std::vector<lmb_match> matches(1000);
  int num_matches = -1;
  ASSERT_EQ(lmb_localize(model, &fx.camera, fx.keypoints.data(), static_cast<int>(fx.keypoints.size()),
                         fx.world.frame.descriptors.data(), test::kCodeDescriptorBytes, gravity, &options, &pose,
                         matches.data(), static_cast<int>(matches.size()), &num_matches),
            LMB_OK)
      << lmb_last_error();

  LocalizerOptions o;
  o.classifier.top_k = 2;
  o.pose.seed = 5;
  const Localizer localizer(std::make_shared<const Model>(fx.model.data()), o);
  const LocalizeResult r =
      localizer.localize(fx.world.frame.camera, fx.world.frame.keypoints, fx.world.frame.descriptors.data(), g);
  ASSERT_TRUE(r.pose.success);
  EXPECT_EQ(pose.success, 1);
  EXPECT_EQ(pose.num_inliers, r.pose.num_inliers);
  EXPECT_EQ(pose.num_correspondences, static_cast<int>(r.correspondence_keypoint.size()));
  EXPECT_EQ(pose.rotation[0], r.pose.cam_from_world.rotation.w());
  EXPECT_EQ(pose.rotation[3], r.pose.cam_from_world.rotation.z());
  EXPECT_EQ(pose.translation[1], r.pose.cam_from_world.translation.y());
  EXPECT_LT(position_error(r.pose.cam_from_world, fx.world.frame.cam_from_world), 1e-3);
  ASSERT_EQ(num_matches, static_cast<int>(r.matches.matches.size()));
  int inliers = 0;
  for (int i = 0; i < num_matches; ++i) {
    const ClassMatch& m = r.matches.matches[i];
    EXPECT_EQ(matches[i].class_id, m.cls);
    EXPECT_EQ(matches[i].landmark, m.landmark);
    EXPECT_EQ(matches[i].score, m.score);
    EXPECT_EQ(matches[i].position[2], fx.model.class_position(m.cls).z());
    EXPECT_GE(matches[i].keypoint, 0);
    inliers += matches[i].inlier;
  }
  EXPECT_EQ(inliers, pose.num_inliers);

  // A buffer too small: the count, the first matches and the pose are still given.
  lmb_pose pose2;
  int n2 = 0;
  EXPECT_EQ(lmb_localize(model, &fx.camera, fx.keypoints.data(), static_cast<int>(fx.keypoints.size()),
                         fx.world.frame.descriptors.data(), test::kCodeDescriptorBytes, gravity, &options, &pose2,
                         matches.data(), 3, &n2),
            LMB_ERROR_BUFFER_TOO_SMALL);
  EXPECT_EQ(n2, num_matches);
  EXPECT_EQ(pose2.success, 1);
  EXPECT_NE(std::string(lmb_last_error()).find("buffer"), std::string::npos);
  lmb_model_free(model);
}

// lmb_localize_with_confidence: the calibrated probability of the C++ Localizer, recomputed here
// from the pose's evidence; the model's threshold decides lmb_pose.success; an uncalibrated model
// gives -1 and the inlier rule.
TEST(CApiTest, ReturnsTheCalibratedProbability) {
  CFixture fx;
  ModelData d = fx.model.data();
  PoseCalibration c;
  c.weights = {0.9, 1.5, -2.0, 0.5, 0.7, 0.3, -0.2};
  c.bias = -3.0;
  c.num_samples = 10;
  c.num_positive = 5;
  c.target_precision = 0.95;
  const Eigen::Vector3d& g = fx.world.frame.gravity_in_cam;
  const double gravity[3] = {g.x(), g.y(), g.z()};
  const LocalizeResult reference =
      Localizer(std::make_shared<const Model>(d))
          .localize(fx.world.frame.camera, fx.world.frame.keypoints, fx.world.frame.descriptors.data(), g);
  ASSERT_TRUE(reference.pose.success);
  EXPECT_FALSE(reference.calibrated);
  EXPECT_EQ(reference.confidence, -1.0);
  EXPECT_TRUE(reference.localized);
  const double p = c.probability(reference.evidence);
  ASSERT_GT(p, 0.0);
  ASSERT_LT(p, 1.0);
  EXPECT_GT(reference.evidence.num_inliers, 0);
  EXPECT_EQ(reference.evidence.num_inliers, reference.pose.num_inliers);
  for (double threshold : {0.5 * p, std::nextafter(p, 2.0)}) {
    c.threshold = threshold;
    d.calibration = c;
    const Model calibrated(d);
    const std::filesystem::path path =
        std::filesystem::temp_directory_path() / ("lmb_c_api_calibrated_test_" + std::to_string(::getpid()) + ".lbm");
    calibrated.save(path);
    lmb_model* model = nullptr;
    ASSERT_EQ(lmb_model_load(path.c_str(), &model), LMB_OK) << lmb_last_error();
    std::filesystem::remove(path);
    EXPECT_EQ(lmb_model_is_calibrated(model), 1);
    lmb_pose pose;
    lmb_pose_confidence confidence;
    ASSERT_EQ(
        lmb_localize_with_confidence(model, &fx.camera, fx.keypoints.data(), static_cast<int>(fx.keypoints.size()),
                                     fx.world.frame.descriptors.data(), test::kCodeDescriptorBytes, gravity, nullptr,
                                     &pose, &confidence, nullptr, 0, nullptr),
        LMB_OK)
        << lmb_last_error();
    EXPECT_EQ(confidence.calibrated, 1);
    EXPECT_EQ(confidence.probability, p);
    EXPECT_EQ(confidence.threshold, threshold);
    EXPECT_EQ(confidence.pose_found, 1);
    const int trusted = threshold <= p ? 1 : 0;
    EXPECT_EQ(confidence.localized, trusted);
    EXPECT_EQ(pose.success, trusted);
    EXPECT_EQ(pose.num_inliers, reference.pose.num_inliers);
    // lmb_localize applies the same rule.
    lmb_pose plain;
    ASSERT_EQ(lmb_localize(model, &fx.camera, fx.keypoints.data(), static_cast<int>(fx.keypoints.size()),
                           fx.world.frame.descriptors.data(), test::kCodeDescriptorBytes, gravity, nullptr, &plain,
                           nullptr, 0, nullptr),
              LMB_OK);
    EXPECT_EQ(plain.success, trusted);
    lmb_model_free(model);
  }
  // The uncalibrated model.
  lmb_model* model = nullptr;
  ASSERT_EQ(lmb_model_load(fx.path.c_str(), &model), LMB_OK) << lmb_last_error();
  EXPECT_EQ(lmb_model_is_calibrated(model), 0);
  EXPECT_EQ(lmb_model_is_calibrated(nullptr), -1);
  lmb_pose pose;
  lmb_pose_confidence confidence;
  ASSERT_EQ(lmb_localize_with_confidence(model, &fx.camera, fx.keypoints.data(), static_cast<int>(fx.keypoints.size()),
                                         fx.world.frame.descriptors.data(), test::kCodeDescriptorBytes, gravity,
                                         nullptr, &pose, &confidence, nullptr, 0, nullptr),
            LMB_OK);
  EXPECT_EQ(confidence.calibrated, 0);
  EXPECT_EQ(confidence.probability, -1.0);
  EXPECT_EQ(confidence.threshold, -1.0);
  EXPECT_EQ(confidence.localized, 1);
  EXPECT_EQ(pose.success, 1);
  lmb_model_free(model);
}

// lmb_walk_localize: the verdicts of the C++ WalkTracker fed with the C++ Localizer's results, frame
// after frame (the first frame by the pose calibration, the next ones by the walk rule too); a
// model without a pose calibration is refused; reset forgets the walk.
TEST(CApiTest, WalkLocalizesLikeTheCppTracker) {
  CFixture fx;
  ModelData d = fx.model.data();
  const Eigen::Vector3d& g = fx.world.frame.gravity_in_cam;
  const double gravity[3] = {g.x(), g.y(), g.z()};
  const int n = static_cast<int>(fx.keypoints.size());
  {
    lmb_model* plain = nullptr;
    ASSERT_EQ(lmb_model_load(fx.path.c_str(), &plain), LMB_OK);
    lmb_walk* walk = reinterpret_cast<lmb_walk*>(1);
    EXPECT_EQ(lmb_walk_create(plain, &walk), LMB_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(walk, nullptr);
    EXPECT_NE(std::string(lmb_last_error()).find("pose calibration"), std::string::npos) << lmb_last_error();
    lmb_model_free(plain);
  }
  PoseCalibration c;
  c.weights = {0.9, 1.5, -2.0, 0.5, 0.7, 0.3, -0.2};
  c.bias = -3.0;
  WalkCalibration w;
  w.weights = {1.0, -2.0, -2.0, -1.0};
  w.bias = 2.0;
  w.translation_scale_m = 0.1;
  w.rotation_scale_deg = 1.0;
  const LocalizeResult reference =
      Localizer(std::make_shared<const Model>(d))
          .localize(fx.world.frame.camera, fx.world.frame.keypoints, fx.world.frame.descriptors.data(), g);
  ASSERT_TRUE(reference.pose.success);
  // The frame rule reports the pose; the walk rule's probability of the same pose again is its own.
  c.threshold = c.probability(reference.evidence);
  w.threshold = 0.5;
  d.calibration = c;
  d.walk_calibration = w;
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("lmb_c_api_walk_test_" + std::to_string(::getpid()) + ".lbm");
  Model(d).save(path);
  lmb_model* model = nullptr;
  ASSERT_EQ(lmb_model_load(path.c_str(), &model), LMB_OK) << lmb_last_error();
  std::filesystem::remove(path);
  lmb_walk* walk = nullptr;
  ASSERT_EQ(lmb_walk_create(model, &walk), LMB_OK) << lmb_last_error();
  EXPECT_EQ(lmb_walk_is_calibrated(walk), 1);
  EXPECT_EQ(lmb_walk_is_calibrated(nullptr), -1);
  WalkTracker tracker(c, w);
  for (int frame = 0; frame < 4; ++frame) {
    if (frame == 3) {
      lmb_walk_reset(walk);
      tracker.reset();
    }
    const WalkVerdict v = tracker.update(true, reference.pose.cam_from_world, reference.evidence);
    lmb_pose pose;
    lmb_pose_confidence confidence;
    int continued = -1;
    ASSERT_EQ(lmb_walk_localize(walk, &fx.camera, fx.keypoints.data(), n, fx.world.frame.descriptors.data(),
                                test::kCodeDescriptorBytes, gravity, nullptr, &pose, &confidence, &continued),
              LMB_OK)
        << lmb_last_error();
    EXPECT_EQ(continued, v.continues ? 1 : 0) << "frame " << frame;
    EXPECT_EQ(frame > 0 && frame < 3, v.continues) << "frame " << frame;
    EXPECT_EQ(pose.success, v.localized ? 1 : 0) << "frame " << frame;
    EXPECT_EQ(confidence.localized, pose.success);
    EXPECT_EQ(confidence.probability, v.continues ? v.walk_confidence : v.frame_confidence) << "frame " << frame;
    EXPECT_EQ(confidence.threshold, v.continues ? w.threshold : c.threshold);
    EXPECT_EQ(pose.num_inliers, reference.pose.num_inliers);
  }
  lmb_walk_free(walk);
  lmb_walk_free(nullptr);
  lmb_model_free(model);
}

// struct_size lets the options grow: the library reads the caller's struct_size bytes and gives
// the fields past them their defaults, so a caller built against an older, shorter struct keeps
// working; fields of a newer caller's longer struct that this library does not know are ignored; a
// size below the first version's (every field through seed) is an error.
TEST(CApiTest, OptionsStructSizeKeepsOlderCallersWorking) {
  CFixture fx;
  lmb_model* model = nullptr;
  ASSERT_EQ(lmb_model_load(fx.path.c_str(), &model), LMB_OK) << lmb_last_error();
  const Eigen::Vector3d& g = fx.world.frame.gravity_in_cam;
  const double gravity[3] = {g.x(), g.y(), g.z()};
  auto run = [&](const lmb_localize_options* o, lmb_pose* pose) {
    return lmb_localize(model, &fx.camera, fx.keypoints.data(), static_cast<int>(fx.keypoints.size()),
                        fx.world.frame.descriptors.data(), test::kCodeDescriptorBytes, gravity, o, pose, nullptr, 0,
                        nullptr);
  };
  lmb_localize_options defaults;
  lmb_localize_options_init(&defaults);
  EXPECT_EQ(defaults.struct_size, sizeof(lmb_localize_options));
  lmb_pose want;
  ASSERT_EQ(run(&defaults, &want), LMB_OK) << lmb_last_error();
  ASSERT_EQ(want.success, 1);
  // A newer caller's longer struct: its extra bytes (here garbage) are not read as options.
  struct Newer {
    lmb_localize_options known;
    unsigned char unknown[64];
  } newer;
  newer.known = defaults;
  newer.known.struct_size = sizeof(Newer);
  std::memset(newer.unknown, 0xAB, sizeof(newer.unknown));
  lmb_pose got;
  ASSERT_EQ(run(&newer.known, &got), LMB_OK) << lmb_last_error();
  EXPECT_EQ(got.success, 1);
  EXPECT_EQ(got.num_inliers, want.num_inliers);
  EXPECT_EQ(got.rotation[0], want.rotation[0]);
  EXPECT_EQ(got.translation[2], want.translation[2]);
  // The caller's fields are used.
  lmb_localize_options strict = defaults;
  strict.min_inliers = 1000000;
  ASSERT_EQ(run(&strict, &got), LMB_OK) << lmb_last_error();
  EXPECT_EQ(got.success, 0);
  // A field appended later (inverted_file_words): a caller whose struct ends before it gets its
  // default whatever lies there; one that sets it out of range gets an error naming it; 2 words
  // a keypoint localizes.
  lmb_localize_options first_version = defaults;
  first_version.inverted_file_words = 0;
  first_version.struct_size = offsetof(lmb_localize_options, seed) + sizeof(uint64_t);
  ASSERT_EQ(run(&first_version, &got), LMB_OK) << lmb_last_error();
  EXPECT_EQ(got.num_inliers, want.num_inliers);
  lmb_localize_options words = defaults;
  words.inverted_file_words = 0;
  EXPECT_EQ(run(&words, &got), LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(lmb_last_error()).find("inverted_file_words = 0"), std::string::npos) << lmb_last_error();
  words.inverted_file_words = 2;
  words.use_inverted_file = 1;
  ASSERT_EQ(run(&words, &got), LMB_OK) << lmb_last_error();
  EXPECT_EQ(got.success, 1);
  // Shorter than the first version: an error naming the field.
  for (size_t size : {size_t{0}, offsetof(lmb_localize_options, seed)}) {
    lmb_localize_options bad = defaults;
    bad.struct_size = size;
    EXPECT_EQ(run(&bad, &got), LMB_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(lmb_last_error()).find("struct_size"), std::string::npos) << lmb_last_error();
  }
  lmb_model_free(model);
}

TEST(CApiTest, VersionComesFromTheBuild) {
  EXPECT_STREQ(lmb_version(), LMB_VERSION_STRING);
  EXPECT_EQ(std::string(lmb_version()), std::to_string(LMB_VERSION_MAJOR) + "." + std::to_string(LMB_VERSION_MINOR) +
                                            "." + std::to_string(LMB_VERSION_PATCH));
}

TEST(CApiTest, ErrorsAreStatusesWithMessages) {
  CFixture fx;
  lmb_model* model = reinterpret_cast<lmb_model*>(0x1);
  EXPECT_EQ(lmb_model_load("/nonexistent/model.lbm", &model), LMB_ERROR_MODEL_FILE);
  EXPECT_EQ(model, nullptr);
  EXPECT_NE(std::string(lmb_last_error()).find("/nonexistent/model.lbm"), std::string::npos);
  // A folder given as the model: a model-file error naming it, not LMB_ERROR_INTERNAL.
  const std::string folder = std::filesystem::temp_directory_path().string();
  EXPECT_EQ(lmb_model_load(folder.c_str(), &model), LMB_ERROR_MODEL_FILE);
  EXPECT_EQ(std::string(lmb_last_error()), "lmb_model_load: " + folder + ": is a folder, not a file");
  EXPECT_EQ(lmb_model_load(nullptr, &model), LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lmb_model_load(fx.path.c_str(), nullptr), LMB_ERROR_INVALID_ARGUMENT);

  // A corrupt image in memory.
  std::vector<uint8_t> bytes = fx.model.to_bytes();
  bytes[bytes.size() / 2] ^= 1;
  EXPECT_EQ(lmb_model_load_from_memory(bytes.data(), bytes.size(), &model), LMB_ERROR_MODEL_FILE);
  EXPECT_NE(std::string(lmb_last_error()).find("CRC"), std::string::npos);
  bytes[bytes.size() / 2] ^= 1;
  ASSERT_EQ(lmb_model_load_from_memory(bytes.data(), bytes.size(), &model), LMB_OK);

  const double gravity[3] = {0, 1, 0};
  const double zero[3] = {0, 0, 0};
  lmb_pose pose;
  const int n = static_cast<int>(fx.keypoints.size());
  const uint8_t* desc = fx.world.frame.descriptors.data();
  EXPECT_EQ(
      lmb_localize(model, &fx.camera, fx.keypoints.data(), n, desc, 32, gravity, nullptr, &pose, nullptr, 0, nullptr),
      LMB_ERROR_INVALID_ARGUMENT);  // wrong descriptor length
  EXPECT_NE(std::string(lmb_last_error()).find("bytes"), std::string::npos);
  EXPECT_EQ(lmb_localize(model, &fx.camera, fx.keypoints.data(), n, desc, test::kCodeDescriptorBytes, zero, nullptr,
                         &pose, nullptr, 0, nullptr),
            LMB_ERROR_INVALID_ARGUMENT);  // zero gravity: an lmb::Error inside, a status outside
  EXPECT_NE(std::string(lmb_last_error()).find("gravity"), std::string::npos) << lmb_last_error();
  lmb_camera bad = fx.camera;
  bad.model = 99;
  EXPECT_EQ(lmb_localize(model, &bad, fx.keypoints.data(), n, desc, test::kCodeDescriptorBytes, gravity, nullptr, &pose,
                         nullptr, 0, nullptr),
            LMB_ERROR_INVALID_ARGUMENT);
  lmb_localize_options options;
  lmb_localize_options_init(&options);
  options.top_k = 0;
  EXPECT_EQ(lmb_localize(model, &fx.camera, fx.keypoints.data(), n, desc, test::kCodeDescriptorBytes, gravity, &options,
                         &pose, nullptr, 0, nullptr),
            LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lmb_localize(nullptr, &fx.camera, fx.keypoints.data(), n, desc, test::kCodeDescriptorBytes, gravity,
                         nullptr, &pose, nullptr, 0, nullptr),
            LMB_ERROR_INVALID_ARGUMENT);
  // Without a matches buffer: the pose and the match count alone.
  int count = 0;
  EXPECT_EQ(lmb_localize(model, &fx.camera, fx.keypoints.data(), n, desc, test::kCodeDescriptorBytes, gravity, nullptr,
                         &pose, nullptr, 0, &count),
            LMB_OK);
  EXPECT_GT(count, 0);
  EXPECT_EQ(pose.success, 1);
  lmb_model_free(model);
  lmb_model_free(nullptr);
}

// The last error is per thread: a thread that made no call sees none. (Named *Thread*: the cross
// test's qemu check skips tests that start threads when its qemu cannot, scripts/cross_test.sh.)
TEST(CApiTest, LastErrorIsPerThread) {
  lmb_model* model = nullptr;
  EXPECT_EQ(lmb_model_load("/nonexistent/model.lbm", &model), LMB_ERROR_MODEL_FILE);
  ASSERT_NE(std::string(lmb_last_error()), "");
  std::string other = "unset";
  std::thread([&] { other = lmb_last_error(); }).join();
  EXPECT_EQ(other, "");
  EXPECT_NE(std::string(lmb_last_error()), "");
}

// CRC-32 (IEEE, reflected), bit by bit: the bundle index's checksum, computed here independently.
uint32_t reference_crc32(const std::string& bytes) {
  uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char c : bytes) {
    crc ^= c;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

// A two-area bundle: area 0 (x >= 25) holds another world's model moved 50 m away, area 1 (x < 25)
// the frame's own model.
struct CBundleFixture : CFixture {
  std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("lmb_c_api_bundle_test_" + std::to_string(::getpid()));
  std::filesystem::path index = dir / "bundle.txt";
  CBundleFixture() {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const test::TestWorld other = test::make_test_world(101, 60, 140, 99);
    std::vector<Eigen::Vector3d> far = other.positions;
    for (auto& p : far) p += Eigen::Vector3d(50, 0, 0);
    const Model far_model(test::make_code_model_data(far, 7));
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<BundleArea> areas(2);
    for (int32_t id = 0; id < 2; ++id) {
      const std::string file = "area-" + std::to_string(id) + ".lbm";
      const Model& area_model = id == 0 ? far_model : model;
      area_model.save(dir / file);
      std::ifstream in(dir / file, std::ios::binary);
      const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      BundleArea& a = areas[id];
      a = describe_area(id, file, bytes, area_model);
      EXPECT_EQ(a.crc32, reference_crc32(bytes));
      a.cell_lo = Eigen::Vector3d(id == 0 ? 25.0 : -inf, -inf, -inf);
      a.cell_hi = Eigen::Vector3d(id == 0 ? inf : 25.0, inf, inf);
    }
    test::write_test_bundle(index, 1.0, areas);
    // The same areas with a bundle calibration that accepts every pose, and one that accepts none.
    for (double bias : {50.0, -50.0}) {
      PoseCalibration c;
      c.bias = bias;
      c.threshold = 0.5;
      test::write_test_bundle(dir / (bias > 0 ? "accept.txt" : "reject.txt"), 1.0, areas, &c);
    }
  }
  ~CBundleFixture() { std::filesystem::remove_all(dir); }
};

TEST(CApiTest, BundleLocalizesAndTracksLikeTheCppApi) {
  CBundleFixture fx;
  EXPECT_EQ(reference_crc32("123456789"), 0xCBF43926u);
  lmb_bundle* bundle = nullptr;
  ASSERT_EQ(lmb_bundle_open(fx.index.c_str(), &bundle), LMB_OK) << lmb_last_error();
  EXPECT_EQ(lmb_bundle_num_areas(bundle), 2);
  EXPECT_EQ(lmb_bundle_num_loaded(bundle), 0);
  const test::TestFrame& f = fx.world.frame;
  const double gravity[3] = {f.gravity_in_cam.x(), f.gravity_in_cam.y(), f.gravity_in_cam.z()};
  const int n = static_cast<int>(fx.keypoints.size());
  lmb_pose pose;
  int area = -2;
  // No prior: both areas compete, the frame's own wins; the same pose as the C++ API.
  ASSERT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                test::kCodeDescriptorBytes, gravity, nullptr, nullptr, &pose, &area),
            LMB_OK)
      << lmb_last_error();
  EXPECT_EQ(lmb_bundle_num_loaded(bundle), 2);
  const auto cpp_bundle = AreaBundle::open(fx.index);
  const BundleLocalizeResult want =
      BundleLocalizer(cpp_bundle).localize(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, nullptr);
  ASSERT_EQ(want.area, 1);
  EXPECT_EQ(area, 1);
  EXPECT_EQ(pose.success, 1);
  EXPECT_EQ(pose.num_inliers, want.result.pose.num_inliers);
  EXPECT_EQ(pose.translation[0], want.result.pose.cam_from_world.translation.x());
  EXPECT_EQ(pose.rotation[0], want.result.pose.cam_from_world.rotation.w());
  EXPECT_LT(position_error(want.result.pose.cam_from_world, f.cam_from_world), 1e-3);
  // A prior at the far area: only it is scored, and it does not give the frame's pose.
  lmb_prior prior = {{50.0, 0.0, 0.0}, 5.0};
  ASSERT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                test::kCodeDescriptorBytes, gravity, &prior, nullptr, &pose, &area),
            LMB_OK);
  EXPECT_NE(area, 1);
  // A prior at the camera: its own area.
  const Eigen::Vector3d c = f.cam_from_world.center();
  prior = lmb_prior{{c.x(), c.y(), c.z()}, 2.0};
  ASSERT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                test::kCodeDescriptorBytes, gravity, &prior, nullptr, &pose, &area),
            LMB_OK);
  EXPECT_EQ(area, 1);
  EXPECT_EQ(pose.num_inliers, want.result.pose.num_inliers);
  // The cache limit applies at once, and a frame needing both areas leaves one loaded.
  ASSERT_EQ(lmb_bundle_set_cache(bundle, 1, 0), LMB_OK);
  EXPECT_EQ(lmb_bundle_num_loaded(bundle), 1);
  ASSERT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                test::kCodeDescriptorBytes, gravity, nullptr, nullptr, &pose, &area),
            LMB_OK);
  EXPECT_EQ(area, 1);
  EXPECT_EQ(lmb_bundle_num_loaded(bundle), 1);
  // Tracking: the first frame in every area, the next with the last pose as the prior; whether a
  // pose passed the motion gate (lmb_bundle_tracked) as BundleLocalizer::track says, with the
  // default two areas judged and with one.
  EXPECT_EQ(lmb_bundle_tracked(bundle), 0);
  EXPECT_EQ(lmb_bundle_tracked(nullptr), -1);
  for (int areas : {2, 1}) {
    lmb::BundleLocalizerOptions options;
    options.tracking_radius = 1.0;
    options.tracking_areas = areas;
    lmb::BundleLocalizer reference(lmb::AreaBundle::open(fx.index), options);
    lmb_bundle* tracking = nullptr;
    ASSERT_EQ(lmb_bundle_open(fx.index.c_str(), &tracking), LMB_OK);
    if (areas != 2) {
      ASSERT_EQ(lmb_bundle_set_tracking_areas(tracking, areas), LMB_OK);
    }
    for (int frame = 0; frame < 2; ++frame) {
      ASSERT_EQ(lmb_bundle_track(tracking, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                 test::kCodeDescriptorBytes, gravity, 1.0, nullptr, &pose, &area),
                LMB_OK)
          << lmb_last_error();
      const lmb::BundleLocalizeResult r =
          reference.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
      EXPECT_EQ(area, 1);
      EXPECT_EQ(area, r.area);
      EXPECT_EQ(pose.num_inliers, want.result.pose.num_inliers);
      EXPECT_EQ(lmb_bundle_tracked(tracking), r.tracked ? 1 : 0) << areas << " " << frame;
      EXPECT_EQ(r.tracked, frame == 1) << areas << " " << frame;  // the first frame has no last pose
    }
    lmb_bundle_free(tracking);
  }
  // A relocalization prior (lmb_bundle_track_with_prior, e.g. GPS): a frame without a last pose is
  // localized in the areas the prior selects, as BundleLocalizer::track with that prior says. At
  // the far area the frame's own area is never scored (no pose of it, nothing to track from); at
  // the camera it is; the next frame, without a prior, is tracked from that pose.
  {
    lmb::BundleLocalizerOptions options;
    options.tracking_radius = 1.0;
    lmb::BundleLocalizer reference(lmb::AreaBundle::open(fx.index), options);
    lmb_bundle* tracking = nullptr;
    ASSERT_EQ(lmb_bundle_open(fx.index.c_str(), &tracking), LMB_OK);
    const lmb_prior far = {{50.0, 0.0, 0.0}, 5.0}, at_camera = {{c.x(), c.y(), c.z()}, 2.0};
    const lmb_prior* priors[3] = {&far, &at_camera, nullptr};
    for (int frame = 0; frame < 3; ++frame) {
      const lmb_prior* p = priors[frame];
      ASSERT_EQ(lmb_bundle_track_with_prior(tracking, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                            test::kCodeDescriptorBytes, gravity, 1.0, p, nullptr, &pose, &area),
                LMB_OK)
          << lmb_last_error();
      lmb::PositionPrior cpp;
      if (p != nullptr) cpp = {Eigen::Vector3d(p->position[0], p->position[1], p->position[2]), p->radius};
      const lmb::BundleLocalizeResult r =
          reference.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, p ? &cpp : nullptr);
      EXPECT_EQ(area, r.area) << frame;
      EXPECT_EQ(pose.num_inliers, r.result.pose.num_inliers) << frame;
      EXPECT_EQ(lmb_bundle_tracked(tracking), r.tracked ? 1 : 0) << frame;
      EXPECT_EQ(area == 1, frame > 0) << frame;
      EXPECT_EQ(r.tracked, frame == 2) << frame;
      EXPECT_EQ(std::find(r.scored.begin(), r.scored.end(), 1) != r.scored.end(), frame > 0) << frame;
    }
    // A bad prior is an error on a frame that would be tracked too (no relocalization needed).
    lmb_prior bad = at_camera;
    bad.radius = -1.0;
    EXPECT_EQ(lmb_bundle_track_with_prior(tracking, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                          test::kCodeDescriptorBytes, gravity, 1.0, &bad, nullptr, &pose, &area),
              LMB_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(lmb_last_error()).find("lmb_bundle_track_with_prior: position prior: radius -1"),
              std::string::npos)
        << lmb_last_error();
    EXPECT_EQ(area, -1);
    EXPECT_EQ(lmb_bundle_tracked(tracking), 0);
    bad = at_camera;
    bad.position[1] = std::numeric_limits<double>::quiet_NaN();
    EXPECT_EQ(lmb_bundle_track_with_prior(tracking, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                          test::kCodeDescriptorBytes, gravity, 1.0, &bad, nullptr, &pose, &area),
              LMB_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(lmb_last_error()).find("not finite"), std::string::npos) << lmb_last_error();
    // The errors left the tracking state alone: the frame is tracked again.
    ASSERT_EQ(lmb_bundle_track_with_prior(tracking, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                          test::kCodeDescriptorBytes, gravity, 1.0, &at_camera, nullptr, &pose, &area),
              LMB_OK);
    EXPECT_EQ(lmb_bundle_tracked(tracking), 1);
    EXPECT_EQ(area, 1);
    lmb_bundle_free(tracking);
  }
  EXPECT_EQ(lmb_bundle_set_tracking_areas(bundle, 0), LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(lmb_last_error()).find("1..256"), std::string::npos) << lmb_last_error();
  EXPECT_EQ(lmb_bundle_set_tracking_areas(bundle, 257), LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lmb_bundle_set_tracking_areas(nullptr, 1), LMB_ERROR_INVALID_ARGUMENT);
  // The options as lmb_localize reads them: a size below the first version's is an error.
  lmb_localize_options older;
  lmb_localize_options_init(&older);
  older.struct_size = 0;
  for (int track = 0; track < 2; ++track) {
    const lmb_status status =
        track ? lmb_bundle_track(bundle, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                 test::kCodeDescriptorBytes, gravity, 1.0, &older, &pose, &area)
              : lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                    test::kCodeDescriptorBytes, gravity, nullptr, &older, &pose, &area);
    EXPECT_EQ(status, LMB_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(lmb_last_error()).find("struct_size"), std::string::npos) << lmb_last_error();
  }
  lmb_bundle_free(bundle);
  lmb_bundle_free(nullptr);
  // A calibrated bundle: success is its answer to act on (the confidence at the operating point),
  // whatever the pose; the winning area is reported either way.
  for (const char* name : {"accept.txt", "reject.txt"}) {
    lmb_bundle* calibrated = nullptr;
    ASSERT_EQ(lmb_bundle_open((fx.dir / name).c_str(), &calibrated), LMB_OK) << lmb_last_error();
    ASSERT_EQ(lmb_bundle_localize(calibrated, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                  test::kCodeDescriptorBytes, gravity, nullptr, nullptr, &pose, &area),
              LMB_OK);
    EXPECT_EQ(area, 1) << name;
    EXPECT_EQ(pose.success, std::string(name) == "accept.txt" ? 1 : 0) << name;
    EXPECT_EQ(pose.num_inliers, want.result.pose.num_inliers) << name;
    // Tracking: a bundle that trusts no pose never gets a last pose to track from (every frame is
    // relocalized, success 0); one that trusts every pose tracks the second frame (success 1).
    for (int frame = 0; frame < 2; ++frame) {
      ASSERT_EQ(lmb_bundle_track(calibrated, &fx.camera, fx.keypoints.data(), n, f.descriptors.data(),
                                 test::kCodeDescriptorBytes, gravity, 1.0, nullptr, &pose, &area),
                LMB_OK);
      EXPECT_EQ(area, 1) << name << frame;
      EXPECT_EQ(pose.success, std::string(name) == "accept.txt" ? 1 : 0) << name << frame;
    }
    lmb_bundle_free(calibrated);
  }
}

// With a bundle that has a walk calibration, lmb_bundle_track's success is the walk's verdict, as
// BundleLocalizer::track's `localized`: a jump the frame rule reports is refused.
TEST(CApiTest, BundleTrackingReportsTheWalksVerdict) {
  CBundleFixture fx;
  BundleIndex index = read_bundle_index(fx.index);
  index.calibration = test::walk_test_frame_calibration();
  index.walk_calibration = test::walk_test_walk_calibration();
  const std::filesystem::path walk_index = fx.dir / "walk.txt";
  write_bundle_index(walk_index, index);
  lmb::BundleLocalizerOptions options;
  options.tracking_radius = 1.0;
  lmb::BundleLocalizer reference(lmb::AreaBundle::open(walk_index), options);
  lmb_bundle* tracking = nullptr;
  ASSERT_EQ(lmb_bundle_open(walk_index.c_str(), &tracking), LMB_OK) << lmb_last_error();
  const std::vector<test::TestFrame> frames = test::walk_test_frames(fx.world);
  std::vector<int> success;
  for (const test::TestFrame& f : frames) {
    std::vector<lmb_keypoint> keypoints;
    for (const Keypoint& k : f.keypoints) keypoints.push_back({k.x, k.y, k.scale, k.angle});
    const double gravity[3] = {f.gravity_in_cam.x(), f.gravity_in_cam.y(), f.gravity_in_cam.z()};
    lmb_pose pose;
    int area = -2;
    ASSERT_EQ(lmb_bundle_track(tracking, &fx.camera, keypoints.data(), static_cast<int>(keypoints.size()),
                               f.descriptors.data(), test::kCodeDescriptorBytes, gravity, 1.0, nullptr, &pose, &area),
              LMB_OK)
        << lmb_last_error();
    const lmb::BundleLocalizeResult r = reference.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
    ASSERT_TRUE(r.walk_judged);
    EXPECT_EQ(area, r.area);
    EXPECT_EQ(pose.success, r.localized ? 1 : 0);
    success.push_back(pose.success);
    EXPECT_TRUE(&f != &frames.back() || r.frame_localized);  // the jump: the frame rule reports it
  }
  EXPECT_EQ(success, (std::vector<int>{1, 1, 1, 1, 1, 0}));
  lmb_bundle_free(tracking);
}

TEST(CApiTest, BundleErrorsAreStatusesWithMessages) {
  CBundleFixture fx;
  lmb_bundle* bundle = reinterpret_cast<lmb_bundle*>(0x1);
  const std::string missing = (fx.dir / "missing.txt").string();
  EXPECT_EQ(lmb_bundle_open(missing.c_str(), &bundle), LMB_ERROR_MODEL_FILE);
  EXPECT_EQ(bundle, nullptr);
  EXPECT_NE(std::string(lmb_last_error()).find(missing), std::string::npos) << lmb_last_error();
  EXPECT_EQ(lmb_bundle_open(nullptr, &bundle), LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lmb_bundle_open(fx.index.c_str(), nullptr), LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lmb_bundle_num_areas(nullptr), -1);
  EXPECT_EQ(lmb_bundle_num_loaded(nullptr), -1);
  EXPECT_EQ(lmb_bundle_set_cache(nullptr, 1, 0), LMB_ERROR_INVALID_ARGUMENT);

  // Area 1 (the frame's own) damaged: the bundle opens, area 0 alone is scored.
  {
    std::fstream io(fx.dir / "area-1.lbm", std::ios::in | std::ios::out | std::ios::binary);
    io.seekp(100);
    io.put('\x5a');
  }
  ASSERT_EQ(lmb_bundle_open(fx.index.c_str(), &bundle), LMB_OK) << lmb_last_error();
  EXPECT_EQ(lmb_bundle_set_cache(bundle, -1, 0), LMB_ERROR_INVALID_ARGUMENT);
  const test::TestFrame& f = fx.world.frame;
  const double gravity[3] = {f.gravity_in_cam.x(), f.gravity_in_cam.y(), f.gravity_in_cam.z()};
  const int n = static_cast<int>(fx.keypoints.size());
  const uint8_t* desc = f.descriptors.data();
  const int bytes = test::kCodeDescriptorBytes;
  lmb_pose pose;
  int area = -2;
  EXPECT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, desc, bytes, gravity, nullptr, nullptr,
                                &pose, &area),
            LMB_OK)
      << lmb_last_error();
  EXPECT_NE(area, 1);
  // A prior selecting only the damaged area: a model-file error naming it, on one line.
  const Eigen::Vector3d c = f.cam_from_world.center();
  lmb_prior prior = {{c.x(), c.y(), c.z()}, 1.0};
  EXPECT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, desc, bytes, gravity, &prior, nullptr,
                                &pose, &area),
            LMB_ERROR_MODEL_FILE);
  const std::string message = lmb_last_error();
  EXPECT_NE(message.find("area 1 (area-1.lbm): CRC-32 mismatch"), std::string::npos) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  EXPECT_EQ(area, -1);
  EXPECT_EQ(pose.success, 0);
  // Bad arguments.
  EXPECT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, desc, 32, gravity, nullptr, nullptr, &pose,
                                &area),
            LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(lmb_last_error()).find("bytes"), std::string::npos) << lmb_last_error();
  prior.radius = -1.0;
  EXPECT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, desc, bytes, gravity, &prior, nullptr,
                                &pose, &area),
            LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(lmb_last_error()).find("radius"), std::string::npos) << lmb_last_error();
  prior.radius = 1.0;
  prior.position[1] = std::nan("");
  EXPECT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, desc, bytes, gravity, &prior, nullptr,
                                &pose, &area),
            LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lmb_bundle_localize(nullptr, &fx.camera, fx.keypoints.data(), n, desc, bytes, gravity, nullptr, nullptr,
                                &pose, &area),
            LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lmb_bundle_localize(bundle, &fx.camera, nullptr, n, desc, bytes, gravity, nullptr, nullptr, &pose, &area),
            LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, desc, bytes, gravity, nullptr, nullptr,
                                nullptr, &area),
            LMB_ERROR_INVALID_ARGUMENT);
  lmb_localize_options options;
  lmb_localize_options_init(&options);
  options.ransac_iterations = 0;
  EXPECT_EQ(lmb_bundle_localize(bundle, &fx.camera, fx.keypoints.data(), n, desc, bytes, gravity, nullptr, &options,
                                &pose, &area),
            LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(
      lmb_bundle_track(bundle, &fx.camera, fx.keypoints.data(), n, desc, bytes, gravity, -1.0, nullptr, &pose, &area),
      LMB_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(lmb_last_error()).find("tracking_radius"), std::string::npos) << lmb_last_error();
  lmb_bundle_free(bundle);
}

}  // namespace
}  // namespace lmb
