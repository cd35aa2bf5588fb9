// AreaBundle: the index, lazy loading and release, LRU eviction under count and byte limits, a
// damaged or missing area failing alone, prior selection against a brute force, localization
// through the bundle (one area = the single model's result; several areas = the one that holds the
// frame's landmarks wins) and BundleLocalizer's tracking mode.
#include "infer/area_bundle.h"
#include "infer/detail/bundle_search.h"
#include "infer/detail/task_pool.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/file_container.h"
#include "common/file_io.h"
#include "common/random.h"
#include "test/infer/test_models.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;
constexpr double kInf = std::numeric_limits<double>::infinity();

// The message of loading area `id`, which must fail ("" and a test failure when it loads).
std::string load_error(AreaBundle& bundle, int32_t id) {
  try {
    bundle.model(id);
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "area " << id << " loaded";
  return "";
}

class AreaBundleTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_area_bundle_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Writes `model` as FILE in the bundle folder; the index entry with the given cell along x.
  // Saves `model` as area `id` of a bundle in `folder` (default: the test's folder).
  BundleArea add(const Model& model, int32_t id, double x_lo, double x_hi, const fs::path& folder = {}) {
    const fs::path dir = folder.empty() ? dir_ : folder;
    const std::string file = "area-" + std::to_string(id) + ".lbm";
    model.save(dir / file);
    BundleArea a = describe_area(id, file, read_file(dir / file), model);
    a.cell_lo = Eigen::Vector3d(x_lo, -kInf, -kInf);
    a.cell_hi = Eigen::Vector3d(x_hi, kInf, kInf);
    return a;
  }

  // A small world's model, and the model of another world moved 50 m along x: its landmarks are
  // elsewhere, the first world's frame matches few of them.
  struct NearAndFar {
    test::TestWorld world;
    std::shared_ptr<const Model> model, far_model;
  };
  static NearAndFar near_and_far() {
    NearAndFar n{test::make_test_world(101, 60, 140, 21), nullptr, nullptr};
    n.model = std::make_shared<const Model>(test::make_code_model_data(n.world.positions));
    std::vector<Eigen::Vector3d> far = test::make_test_world(101, 60, 140, 99).positions;
    for (auto& p : far) p += Eigen::Vector3d(50, 0, 0);
    n.far_model = std::make_shared<const Model>(test::make_code_model_data(far, 7));
    return n;
  }
  // The frame's landmark classes, in keypoint order.
  static std::vector<int32_t> frame_classes(const test::TestFrame& f) {
    std::vector<int32_t> seen;
    for (int32_t c : f.keypoint_class) {
      if (c >= 0 && std::find(seen.begin(), seen.end(), c) == seen.end()) seen.push_back(c);
    }
    return seen;
  }
  // A model that knows every code of `world` but holds only seen[first, first + count) where they
  // are plus `offset`; every other class sits at a random point ~1 km away (random, so that these
  // points form no pose of their own, and beyond any reach of these tests).
  static std::shared_ptr<const Model> area_model(const test::TestWorld& world, const std::vector<int32_t>& seen,
                                                 Rng& rng, size_t first, size_t count, const Eigen::Vector3d& offset) {
    ModelData d = test::make_code_model_data(world.positions);
    for (auto& p : d.class_position) {
      p = Eigen::Vector3d(rng.uniform(500, 1500), rng.uniform(-500, 500), rng.uniform(-500, 500));
    }
    for (size_t i = first; i < first + count; ++i) d.class_position[seen[i]] = world.positions[seen[i]] + offset;
    return std::make_shared<const Model>(std::move(d));
  }
  // dir_/track.txt, four areas around `world`'s frame (reach 50 m): 0: a look-alike of 45 of its
  // landmarks, 3 m further along the optical axis (its pose lies 3 m behind the camera), in the
  // cell holding the camera; 1: all 60 where they are, 1 m away; 2: 20 of them, 2 m away; 3: none,
  // 1 m away on the other side.
  void write_tracking_bundle(const test::TestWorld& world) {
    const test::TestFrame& f = world.frame;
    const std::vector<int32_t> seen = frame_classes(f);
    Rng rng(29);
    const Eigen::Vector3d axis = f.cam_from_world.rotation.inverse() * Eigen::Vector3d::UnitZ();
    const double x = f.cam_from_world.center().x();
    test::write_test_bundle(dir_ / "track.txt", 50.0,
                            {add(*area_model(world, seen, rng, 0, 45, 3.0 * axis), 0, x - 1.0, x + 1.0),
                             add(*area_model(world, seen, rng, 0, 60, Eigen::Vector3d::Zero()), 1, x + 1.0, x + 2.0),
                             add(*area_model(world, seen, rng, 0, 20, Eigen::Vector3d::Zero()), 2, x + 2.0, kInf),
                             add(*area_model(world, seen, rng, 0, 0, Eigen::Vector3d::Zero()), 3, -kInf, x - 1.0)});
  }
  fs::path dir_;
};

TEST_F(AreaBundleTest, OpensLazilyLoadsOnFirstUseAndReleases) {
  const test::TestWorld world = test::make_test_world(40, 30, 20, 5);
  const Model model(test::make_code_model_data(world.positions));
  std::vector<BundleArea> areas = {add(model, 0, -kInf, 0.0), add(model, 1, 0.0, 10.0), add(model, 2, 10.0, kInf)};
  test::write_test_bundle(dir_ / "bundle.txt", 2.5, areas);
  const auto bundle = AreaBundle::open(dir_ / "bundle.txt");
  ASSERT_EQ(bundle->areas().size(), 3u);
  EXPECT_EQ(bundle->reach(), 2.5);
  EXPECT_EQ(bundle->areas()[1].bytes, areas[1].bytes);
  EXPECT_EQ(bundle->areas()[2].cell_hi.x(), kInf);
  for (int32_t id = 0; id < 3; ++id) EXPECT_FALSE(bundle->loaded(id));
  const auto m1 = bundle->model(1);
  EXPECT_TRUE(bundle->loaded(1));
  EXPECT_FALSE(bundle->loaded(0));
  EXPECT_EQ(bundle->model(1), m1);  // loaded once
  EXPECT_EQ(m1->num_classes(), model.num_classes());
  bundle->model(2);
  bundle->release_except({2});
  EXPECT_FALSE(bundle->loaded(1));
  EXPECT_TRUE(bundle->loaded(2));
  EXPECT_EQ(m1->num_classes(), model.num_classes());  // the caller's copy lives on
}

TEST_F(AreaBundleTest, AModelTransformAppliesToEveryLoadAndItsErrorsAreTheAreas) {
  const test::TestWorld world = test::make_test_world(40, 30, 20, 5);
  const Model model(test::make_code_model_data(world.positions));
  test::write_test_bundle(dir_ / "bundle.txt", 2.5, {add(model, 0, -kInf, 0.0), add(model, 1, 0.0, kInf)});
  const auto bundle = AreaBundle::open(dir_ / "bundle.txt");
  const auto before = bundle->model(0);
  EXPECT_EQ(before->data().bias, model.data().bias);
  // Each load passes through the transform, which sees the area's id and the file's model; the
  // areas loaded before it was set are freed, so no untransformed model is handed out.
  std::vector<int32_t> seen;
  bundle->set_model_transform([&](int32_t id, std::shared_ptr<const Model> m) {
    seen.push_back(id);
    EXPECT_EQ(m->data().bias, model.data().bias);
    ModelData d = m->data();
    d.bias.back() += 1.0 + id;
    return std::make_shared<const Model>(std::move(d));
  });
  EXPECT_FALSE(bundle->loaded(0));
  const auto m0 = bundle->model(0);
  const auto m1 = bundle->model(1);
  EXPECT_EQ(bundle->model(1), m1);  // transformed once, then kept
  EXPECT_EQ(seen, (std::vector<int32_t>{0, 1}));
  EXPECT_EQ(m0->data().bias.back(), model.data().bias.back() + 1.0);
  EXPECT_EQ(m1->data().bias.back(), model.data().bias.back() + 2.0);
  EXPECT_EQ(before->data().bias, model.data().bias);  // a caller's earlier copy is untouched
  // A transform that throws, returns nothing or changes the classes fails that load with one line
  // naming the area; the next load tries again.
  bundle->set_model_transform([](int32_t id, std::shared_ptr<const Model> m) -> std::shared_ptr<const Model> {
    if (id == 0) throw Error("no exemplar left");
    return m;
  });
  const std::string thrown = load_error(*bundle, 0);
  EXPECT_NE(thrown.find("area 0 (area-0.lbm): no exemplar left"), std::string::npos) << thrown;
  EXPECT_FALSE(bundle->loaded(0));
  EXPECT_EQ(bundle->model(1)->data().bias, model.data().bias);
  bundle->set_model_transform([](int32_t, std::shared_ptr<const Model>) { return std::shared_ptr<const Model>(); });
  EXPECT_NE(load_error(*bundle, 1).find("area 1 (area-1.lbm): the bundle's model transform returned no model"),
            std::string::npos);
  bundle->set_model_transform([&](int32_t, std::shared_ptr<const Model>) {
    const test::TestWorld other = test::make_test_world(41, 30, 20, 5);
    return std::make_shared<const Model>(test::make_code_model_data(other.positions));
  });
  EXPECT_NE(load_error(*bundle, 1).find("returned a model of other classes"), std::string::npos);
  bundle->set_model_transform({});  // removed: the files' models again
  EXPECT_EQ(bundle->model(0)->data().bias, model.data().bias);
}

TEST_F(AreaBundleTest, EvictsTheLeastRecentlyUsedAreasBeyondTheLimits) {
  const test::TestWorld world = test::make_test_world(40, 30, 20, 5);
  const Model model(test::make_code_model_data(world.positions));
  std::vector<BundleArea> areas;
  for (int32_t i = 0; i < 4; ++i) areas.push_back(add(model, i, i == 0 ? -kInf : i, i == 3 ? kInf : i + 1.0));
  test::write_test_bundle(dir_ / "bundle.txt", 1.0, areas);
  const auto bundle = AreaBundle::open(dir_ / "bundle.txt");
  EXPECT_THROW(bundle->set_cache_limits({-1, 0}), Error);
  bundle->set_cache_limits({2, 0});
  bundle->model(0);
  bundle->model(1);
  EXPECT_EQ(bundle->loaded_ids(), (std::vector<int32_t>{0, 1}));
  bundle->model(0);  // 0 is now the most recently used: loading 2 frees 1
  const auto held = bundle->model(2);
  EXPECT_EQ(bundle->loaded_ids(), (std::vector<int32_t>{0, 2}));
  EXPECT_EQ(bundle->loads(), 3);
  bundle->model(3);  // frees 0 (used before 2)
  EXPECT_EQ(bundle->loaded_ids(), (std::vector<int32_t>{2, 3}));
  bundle->model(1);  // read again: a load
  EXPECT_EQ(bundle->loads(), 5);
  EXPECT_EQ(bundle->loaded_ids(), (std::vector<int32_t>{1, 3}));
  EXPECT_EQ(held->num_classes(), model.num_classes());  // an evicted area held by a caller lives on
  EXPECT_EQ(bundle->loaded_bytes(), areas[1].bytes + areas[3].bytes);
  // A byte limit of one area and a half: one area stays. Lowering a limit applies it at once.
  bundle->set_cache_limits({0, areas[0].bytes + areas[0].bytes / 2});
  EXPECT_EQ(bundle->loaded_ids(), std::vector<int32_t>{1});  // 1 was used last
  bundle->model(2);
  EXPECT_EQ(bundle->loaded_ids(), std::vector<int32_t>{2});
  // A limit below one area keeps the area just loaded.
  bundle->set_cache_limits({0, 1});
  bundle->model(0);
  EXPECT_EQ(bundle->loaded_ids(), std::vector<int32_t>{0});
  // No limit: everything stays.
  bundle->set_cache_limits({});
  for (int32_t id = 0; id < 4; ++id) bundle->model(id);
  EXPECT_EQ(bundle->loaded_ids(), (std::vector<int32_t>{0, 1, 2, 3}));
  // Localizing frame after frame in the areas a moving prior selects keeps at most the limit.
  bundle->release_except({});
  bundle->set_cache_limits({2, 0});
  const test::TestFrame& f = world.frame;
  for (double x : {0.5, 1.5, 2.5, 3.5, 0.5}) {
    PositionPrior prior;
    prior.position = Eigen::Vector3d(x, 0, 0);
    prior.radius = 0.0;
    const BundleLocalizeResult r =
        detail::localize_in_bundle(*bundle, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, &prior);
    EXPECT_FALSE(r.scored.empty());
    EXPECT_LE(bundle->loaded_ids().size(), 2u);
  }
}

TEST_F(AreaBundleTest, ADamagedOrMissingAreaFailsAloneWithOneLine) {
  const test::TestWorld world = test::make_test_world(40, 30, 20, 5);
  const Model model(test::make_code_model_data(world.positions));
  test::write_test_bundle(dir_ / "bundle.txt", 1.0,
                          {add(model, 0, -kInf, 0.0), add(model, 1, 0.0, 10.0), add(model, 2, 10.0, kInf)});
  // Area 1: one byte flipped; area 2: missing.
  std::string image = read_file(dir_ / "area-1.lbm");
  image[image.size() / 2] ^= 0x10;
  write_file_atomically(dir_ / "area-1.lbm", image);
  fs::remove(dir_ / "area-2.lbm");
  const auto bundle = AreaBundle::open(dir_ / "bundle.txt");
  EXPECT_NO_THROW(bundle->model(0));
  for (int32_t id : {1, 2}) {
    const std::string what = load_error(*bundle, id);
    EXPECT_NE(what.find(": area " + std::to_string(id) + " (area-" + std::to_string(id) + ".lbm): "), std::string::npos)
        << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    if (id == 1) {
      EXPECT_NE(what.find("CRC-32 mismatch"), std::string::npos) << what;
    }
  }
  EXPECT_TRUE(bundle->loaded(0));
  // localize_in_bundle scores the good area and reports the others.
  const test::TestFrame& f = world.frame;
  const BundleLocalizeResult r =
      detail::localize_in_bundle(*bundle, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, nullptr);
  EXPECT_EQ(r.scored, std::vector<int32_t>{0});
  EXPECT_EQ(r.errors.size(), 2u);
  EXPECT_EQ(r.area, 0);
}

// The pool that scores a frame's areas: every task of a batch runs once, on up to threads()
// threads at a time, run() returns when all have finished and rethrows the first failure in task
// order; batches of several callers run at once.
TEST(TaskPool, ThreadsRunEveryTaskOnceAndRethrowTheFirstFailure) {
  detail::TaskPool pool(3);
  EXPECT_EQ(pool.threads(), 3);
  std::vector<std::atomic<int>> runs(50);
  std::atomic<int> running{0}, most{0};
  std::vector<std::function<void()>> tasks;
  for (size_t i = 0; i < runs.size(); ++i) {
    tasks.emplace_back([&, i] {
      const int now = ++running;
      for (int m = most; now > m && !most.compare_exchange_weak(m, now);) {
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      ++runs[i];
      --running;
    });
  }
  pool.run(tasks);
  for (const auto& r : runs) EXPECT_EQ(r.load(), 1);
  EXPECT_LE(most.load(), 3);
  std::vector<std::function<void()>> failing = {[] {}, [] { throw Error("second"); }, [] { throw Error("third"); }};
  try {
    pool.run(failing);
    ADD_FAILURE() << "no exception";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "second");
  }
  // Two callers at once, each waits for its own batch.
  std::atomic<int> done{0};
  std::vector<std::function<void()>> batch;
  for (int i = 0; i < 20; ++i) batch.emplace_back([&] { ++done; });
  std::thread other([&] { pool.run(batch); });
  pool.run(batch);
  other.join();
  EXPECT_EQ(done.load(), 40);
  EXPECT_THROW(detail::TaskPool(0), Error);
}

// An area's file replaced by another model, even with the index's bytes and CRC-32 made to match
// it, fails to load alone: its classes are not the ones the index records.
TEST_F(AreaBundleTest, AnAreaWhoseModelIsNotTheIndexedOneFailsAlone) {
  const test::TestWorld world = test::make_test_world(40, 30, 20, 5);
  const Model model(test::make_code_model_data(world.positions));
  std::vector<Eigen::Vector3d> moved = world.positions;
  for (Eigen::Vector3d& p : moved) p.x() += 1e-3;  // another map: the same landmarks 1 mm away
  const Model other(test::make_code_model_data(moved));
  const std::vector<BundleArea> areas = {add(model, 0, -kInf, 0.0), add(model, 1, 0.0, kInf)};
  other.save(dir_ / "area-1.lbm");
  std::vector<BundleArea> forged = areas;
  const BundleArea of_other = describe_area(1, "area-1.lbm", read_file(dir_ / "area-1.lbm"), other);
  forged[1].bytes = of_other.bytes;
  forged[1].crc32 = of_other.crc32;
  test::write_test_bundle(dir_ / "bundle.txt", 1.0, forged);
  const auto bundle = AreaBundle::open(dir_ / "bundle.txt");
  EXPECT_NO_THROW(bundle->model(0));
  const std::string what = load_error(*bundle, 1);
  EXPECT_NE(what.find(": area 1 (area-1.lbm): its classes (landmark ids and positions) differ"), std::string::npos)
      << what;
  EXPECT_FALSE(bundle->loaded(1));
  // The entry's fingerprint is of the classes alone: the same model in another file loads.
  EXPECT_EQ(of_other.classes, fingerprint_classes(other));
  EXPECT_NE(of_other.classes, areas[1].classes);
  EXPECT_EQ(areas[0].classes, areas[1].classes);
}

// Indexes of versions 1 and 2 (no map, areas by class count only) still open and load.
TEST_F(AreaBundleTest, VersionOneAndTwoIndexesStillOpen) {
  const test::TestWorld world = test::make_test_world(10, 8, 2, 5);
  const Model model(test::make_code_model_data(world.positions));
  const BundleArea a = add(model, 0, -kInf, kInf);
  char crc[16];
  std::snprintf(crc, sizeof(crc), "%08x", a.crc32);
  const std::string area_line = "area 0 file area-0.lbm bytes " + std::to_string(a.bytes) + " crc32 " + crc +
                                " landmarks " + std::to_string(a.landmarks) + " cell -inf -inf -inf inf inf inf\n";
  write_file_atomically(dir_ / "v1.txt", "lmb-bundle 1\nreach 1.5\nareas 1\n" + area_line);
  write_file_atomically(dir_ / "v2.txt",
                        "lmb-bundle 2\nreach 1.5\ncalibration 0 0 0 0 0 0 0 0 0.5 10 5 0.95\nareas 1\n" + area_line);
  for (const char* name : {"v1.txt", "v2.txt"}) {
    const auto bundle = AreaBundle::open(dir_ / name);
    EXPECT_EQ(bundle->map_fingerprint(), 0u) << name;
    EXPECT_EQ(bundle->calibrated(), std::string(name) == "v2.txt");
    EXPECT_EQ(bundle->model(0)->num_classes(), model.num_classes());
  }
  // A class count other than the model's is refused on load, in every version.
  std::string wrong = area_line;
  const std::string count = " landmarks " + std::to_string(a.landmarks) + " ";
  wrong.replace(wrong.find(count), count.size(), " landmarks 3 ");
  write_file_atomically(dir_ / "v1.txt", "lmb-bundle 1\nreach 1.5\nareas 1\n" + wrong);
  EXPECT_NE(load_error(*AreaBundle::open(dir_ / "v1.txt"), 0)
                .find(std::to_string(model.num_classes()) + " classes, the bundle index says 3"),
            std::string::npos);
}

// A bundle made in memory (AreaBundle::create) is the bundle its written index opens.
TEST_F(AreaBundleTest, ABundleInMemoryEqualsItsWrittenIndex) {
  const test::TestWorld world = test::make_test_world(10, 8, 2, 5);
  const Model model(test::make_code_model_data(world.positions));
  BundleIndex index;
  index.reach = 2.0;
  index.map_fingerprint = test::kTestMapFingerprint;
  index.areas = {add(model, 0, -kInf, 0.0), add(model, 1, 0.0, kInf)};
  const auto memory = AreaBundle::create(dir_ / "bundle.txt", index);
  EXPECT_FALSE(fs::exists(dir_ / "bundle.txt"));
  write_bundle_index(dir_ / "bundle.txt", index);
  const auto file = AreaBundle::open(dir_ / "bundle.txt");
  EXPECT_EQ(memory->map_fingerprint(), file->map_fingerprint());
  EXPECT_EQ(memory->reach(), file->reach());
  ASSERT_EQ(memory->areas().size(), file->areas().size());
  for (size_t i = 0; i < file->areas().size(); ++i) {
    EXPECT_EQ(memory->areas()[i].classes, file->areas()[i].classes);
    EXPECT_EQ(memory->areas()[i].first_landmark, file->areas()[i].first_landmark);
    EXPECT_EQ(memory->areas()[i].last_landmark, file->areas()[i].last_landmark);
  }
  EXPECT_EQ(memory->model(1)->num_classes(), model.num_classes());
  // The writer refuses what the reader would: a file outside the folder, one file for two areas,
  // no map fingerprint.
  BundleIndex bad = index;
  bad.areas[1].file = "../area-1.lbm";
  EXPECT_THROW(write_bundle_index(dir_ / "bad.txt", bad), Error);
  bad = index;
  bad.areas[1].file = bad.areas[0].file;
  EXPECT_THROW(write_bundle_index(dir_ / "bad.txt", bad), Error);
  bad = index;
  bad.map_fingerprint = 0;
  EXPECT_THROW(write_bundle_index(dir_ / "bad.txt", bad), Error);
  EXPECT_FALSE(fs::exists(dir_ / "bad.txt"));
}

// Every area of a bundle reads the frame's descriptors with one length: an area whose model has
// another fails to load alone (naming both), whichever area loaded first.
TEST_F(AreaBundleTest, AnAreaWithAnotherDescriptorLengthFailsAlone) {
  const test::TestWorld world = test::make_test_world(40, 30, 20, 5);
  const Model model(test::make_code_model_data(world.positions));
  ModelData wide_data = test::make_code_model_data(world.positions);
  wide_data.descriptor_bytes = 2 * test::kCodeDescriptorBytes;
  Rng rng(3);
  std::vector<uint8_t> words(4 * static_cast<size_t>(wide_data.descriptor_bytes));
  for (auto& b : words) b = static_cast<uint8_t>(rng.below(256));
  wide_data.vocabulary = Vocabulary(wide_data.descriptor_bytes, words);
  const Model wide(std::move(wide_data));
  test::write_test_bundle(dir_ / "bundle.txt", 1.0, {add(model, 0, -kInf, 0.0), add(wide, 1, 0.0, kInf)});
  const auto bundle = AreaBundle::open(dir_ / "bundle.txt");
  EXPECT_EQ(bundle->descriptor_bytes(), -1);
  EXPECT_NO_THROW(bundle->model(0));
  EXPECT_EQ(bundle->descriptor_bytes(), test::kCodeDescriptorBytes);
  const std::string what = load_error(*bundle, 1);
  EXPECT_NE(what.find(": area 1 (area-1.lbm): 16-byte descriptors, the bundle's areas loaded before have 8"),
            std::string::npos)
      << what;
  EXPECT_FALSE(bundle->loaded(1));
  const test::TestFrame& f = world.frame;
  const BundleLocalizeResult r =
      detail::localize_in_bundle(*bundle, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, nullptr);
  EXPECT_EQ(r.scored, std::vector<int32_t>{0});
  ASSERT_EQ(r.errors.size(), 1u);
  // The other way round: the wide area first, then the 8-byte one fails.
  const auto other = AreaBundle::open(dir_ / "bundle.txt");
  EXPECT_NO_THROW(other->model(1));
  EXPECT_EQ(other->descriptor_bytes(), 16);
  EXPECT_THROW(other->model(0), Error);
}

TEST_F(AreaBundleTest, RejectsMalformedIndexesNamingTheLine) {
  const test::TestWorld world = test::make_test_world(10, 8, 2, 5);
  const Model model(test::make_code_model_data(world.positions));
  test::write_test_bundle(dir_ / "bundle.txt", 1.0, {add(model, 0, -kInf, kInf)});
  const std::string good = read_file(dir_ / "bundle.txt");
  // An index of this text fails to open with a message naming the file and holding `needle`.
  auto expect_text_rejected = [&](const std::string& text, const std::string& needle) {
    write_file_atomically(dir_ / "bad.txt", text);
    try {
      AreaBundle::open(dir_ / "bad.txt");
      ADD_FAILURE() << "accepted:\n" << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find((dir_ / "bad.txt").string()), std::string::npos) << e.what();
    }
  };
  auto expect_rejected = [&](const std::string& from, const std::string& to, const std::string& needle) {
    std::string text = good;
    const size_t at = text.find(from, text.find("reach"));
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
    expect_text_rejected(text, needle);
  };
  expect_rejected("reach 1", "reach -1", "reach -1 is negative");
  // The line named is the one at fault (the header, a comment, then reach, map and areas).
  expect_rejected("reach 1", "reach x", "bad.txt line 3: reach is not a number: 'x'");
  expect_rejected("map ", "map 0", "bad.txt line 4: map is not 16 hex digits");
  expect_rejected("areas 1", "areas x", "bad.txt line 5: areas is not a number");
  expect_rejected("areas 1", "areas 2", "ends before the 'area' line");
  expect_rejected(" crc32 ", " crc ", "expected 'crc32'");
  expect_rejected(" classes ", " class ", "expected 'classes'");
  // An area's file is a plain name in the bundle's folder.
  for (const std::string name :
       {"/abs/area-0.lbm", "../area-0.lbm", "sub/area-0.lbm", "..", ".", "a\x01.lbm", "a\xff.lbm", "a\xc3.lbm"}) {
    expect_rejected("file area-0.lbm", "file " + name, "must be a file name in the bundle's folder");
  }
  expect_rejected(" cell -inf", " cell inf", "cell on axis 0 lies at infinity");
  // A line of white space only where the calibration or areas line belongs.
  expect_rejected("areas 1", "\v\nareas 1", "bad.txt line 5: expected 'areas'");
  {
    // A landmark range narrower than the class count.
    const size_t at = good.rfind(" first_landmark ") + 16;  // the area line, not the comment
    const std::string first = good.substr(at, good.find(' ', at) - at);
    const size_t last_at = good.rfind(" last_landmark ") + 15;
    const std::string last = good.substr(last_at, good.find(' ', last_at) - last_at);
    expect_rejected(" last_landmark " + last + " ", " last_landmark " + first + " ", "cannot hold");
  }
  // The calibration line is optional; one value short is refused; version 5 is refused.
  const std::string calibration = "calibration 0 0 0 0 0 0 0 0 0.5 1 1 0.9\n";
  expect_rejected("areas 1", "calibration 0 0 0 0 0 0 0 0 0.5 1 1\nareas 1",
                  "bad.txt line 5: expected 'calibration' and 12 value(s)");
  expect_rejected("areas 1", "calibration 0 0 0 0 0 0 0 0 1.5 1 1 0.9\nareas 1", "bad.txt line 5: calibration");
  // The walk calibration: after the calibration only, 17 values, each field checked.
  const std::string walk = "walk_calibration 0 0 0 0 1 0.5 0.01 1 3 1 0.01 0.5 0.01 1 10 5 0.95\n";
  write_file_atomically(dir_ / "walk.txt",
                        good.substr(0, good.find("areas 1")) + calibration + walk + good.substr(good.find("areas 1")));
  EXPECT_EQ(AreaBundle::open(dir_ / "walk.txt")->walk_calibration()->max_gap, 3);
  expect_rejected("areas 1", walk + "areas 1", "bad.txt line 5: expected 'areas'");
  expect_rejected("areas 1", calibration + "walk_calibration 0 0 0 0 1 0.5 0.01 1 3 1\nareas 1",
                  "bad.txt line 6: expected 'walk_calibration' and 17 value(s)");
  expect_rejected("areas 1",
                  calibration + "walk_calibration 0 0 0 0 1 0.5 0.01 1 0 1 0.01 0.5 0.01 1 10 5 0.95\nareas 1",
                  "bad.txt line 6: walk calibration");
  expect_rejected("areas 1",
                  calibration + "walk_calibration 0 0 0 0 1 0.5 0.01 1 3 2 0.01 0.5 0.01 1 10 5 0.95\nareas 1",
                  "bad.txt line 6: walk calibration adds");
  expect_rejected("areas 1", calibration + "walk_calibration 0 0 0 0 1 0.5 -1 1 3 1 0.01 0.5 0.01 1 10 5 0.95\nareas 1",
                  "bad.txt line 6: walk calibration");
  std::string v3 = good;
  v3.replace(v3.find("lmb-bundle 4"), 12, "lmb-bundle 3");
  write_file_atomically(dir_ / "v3.txt", v3);
  EXPECT_FALSE(AreaBundle::open(dir_ / "v3.txt")->walk_calibration().has_value());
  std::string v3_walk = v3.substr(0, v3.find("areas 1")) + calibration + walk + v3.substr(v3.find("areas 1"));
  expect_text_rejected(v3_walk, "bad.txt line 6: expected 'areas'");  // a version 3 index has no walk line
  std::string v5 = good;
  v5.replace(v5.find("lmb-bundle 4"), 12, "lmb-bundle 5");
  expect_text_rejected(v5, "bad.txt line 1: format version 5 is not supported");
  EXPECT_THROW(AreaBundle::open(dir_ / "missing.txt"), Error);
}

TEST_F(AreaBundleTest, PriorSelectsTheAreasWithinRadiusPlusReach) {
  const test::TestWorld world = test::make_test_world(10, 8, 2, 5);
  const Model model(test::make_code_model_data(world.positions));
  std::vector<BundleArea> areas;
  const std::vector<double> cuts = {-kInf, 0.0, 4.0, 8.0, 12.0, kInf};
  for (int32_t i = 0; i < 5; ++i) areas.push_back(add(model, i, cuts[i], cuts[i + 1]));
  test::write_test_bundle(dir_ / "bundle.txt", 1.5, areas);
  const auto bundle = AreaBundle::open(dir_ / "bundle.txt");
  EXPECT_EQ(bundle->select(nullptr), (std::vector<int32_t>{0, 1, 2, 3, 4}));
  PositionPrior prior;
  prior.position = Eigen::Vector3d(6.0, 0.0, 0.0);
  prior.radius = 0.0;
  EXPECT_EQ(bundle->select(&prior), (std::vector<int32_t>{2}));  // 2 m from both borders > reach
  prior.radius = 1.0;
  EXPECT_EQ(bundle->select(&prior), (std::vector<int32_t>{1, 2, 3}));
  Rng rng(3);
  for (int trial = 0; trial < 500; ++trial) {
    prior.position = Eigen::Vector3d(rng.uniform(-5, 17), rng.uniform(-3, 3), rng.uniform(-3, 3));
    prior.radius = rng.uniform(0, 5);
    std::vector<int32_t> want;  // brute force along x (the cells are slabs)
    for (int32_t i = 0; i < 5; ++i) {
      const double x = prior.position.x();
      const double d = x < cuts[i] ? cuts[i] - x : (x > cuts[i + 1] ? x - cuts[i + 1] : 0.0);
      if (d <= prior.radius + 1.5) want.push_back(i);
    }
    EXPECT_EQ(bundle->select(&prior), want);
  }
  prior.radius = -1.0;
  EXPECT_THROW(bundle->select(&prior), Error);
}

TEST_F(AreaBundleTest, OneAreaEqualsTheSingleModelAndTheRightAreaWins) {
  const NearAndFar n = near_and_far();
  const std::shared_ptr<const Model>& model = n.model;
  const Model& far_model = *n.far_model;
  const test::TestFrame& f = n.world.frame;
  test::write_test_bundle(dir_ / "one.txt", 1.0, {add(*model, 0, -kInf, kInf)});
  const auto one = AreaBundle::open(dir_ / "one.txt");
  const BundleLocalizeResult b =
      detail::localize_in_bundle(*one, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, nullptr);
  const LocalizeResult single =
      Localizer(model).localize(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  ASSERT_EQ(b.area, 0);
  ASSERT_TRUE(single.pose.success);
  EXPECT_EQ(b.result.pose.num_inliers, single.pose.num_inliers);
  EXPECT_EQ(b.result.pose.inlier_mask, single.pose.inlier_mask);
  EXPECT_EQ(b.result.pose.cam_from_world.translation, single.pose.cam_from_world.translation);
  EXPECT_EQ(b.result.pose.cam_from_world.rotation.coeffs(), single.pose.cam_from_world.rotation.coeffs());
  EXPECT_EQ(b.result.correspondence_keypoint, single.correspondence_keypoint);
  // Two areas: the far one first, then the frame's own; the own area wins on inliers. With a prior
  // near the far area only, only it is scored.
  test::write_test_bundle(dir_ / "two.txt", 1.0, {add(far_model, 0, 25.0, kInf), add(*model, 1, -kInf, 25.0)});
  const auto two = AreaBundle::open(dir_ / "two.txt");
  const BundleLocalizeResult both =
      detail::localize_in_bundle(*two, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, nullptr);
  EXPECT_EQ(both.scored, (std::vector<int32_t>{0, 1}));
  EXPECT_EQ(both.area, 1);
  EXPECT_EQ(both.inliers[1], single.pose.num_inliers);
  EXPECT_LT(both.inliers[0], both.inliers[1]);
  PositionPrior prior;
  prior.position = Eigen::Vector3d(50, 0, 0);
  prior.radius = 5.0;
  const BundleLocalizeResult far_only =
      detail::localize_in_bundle(*two, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, &prior);
  EXPECT_EQ(far_only.scored, std::vector<int32_t>{0});
}

// An aliased place: area 0 holds look-alikes of 36 of the frame's 60 landmarks, 0.8 m away (the
// same descriptors, shifted positions), so its pose is wrong with 36 inliers; areas 1 and 2 each
// hold the true positions of 30 of them (the view spans both), so their poses are right with 30
// inliers each. Most inliers picks the wrong pose; support over every area's matches (60 keypoints
// explained by the right pose, 36 by the wrong one) picks the right one.
TEST_F(AreaBundleTest, TheWinnerExplainsMostKeypointsWithEveryAreasMatches) {
  const test::TestWorld world = test::make_test_world(101, 60, 140, 21);
  const test::TestFrame& f = world.frame;
  const std::vector<int32_t> seen = frame_classes(f);
  ASSERT_EQ(seen.size(), 60u);
  const Eigen::Vector3d shift(0.8, 0, 0);
  Rng rng(17);
  const auto area_model = [&](size_t first, size_t count, const Eigen::Vector3d& offset) {
    return AreaBundleTest::area_model(world, seen, rng, first, count, offset);
  };
  test::write_test_bundle(
      dir_ / "aliased.txt", 1.0,
      {add(*area_model(0, 36, shift), 0, -kInf, 0.0), add(*area_model(0, 30, {0, 0, 0}), 1, 0.0, 1.0),
       add(*area_model(30, 30, {0, 0, 0}), 2, 1.0, kInf)});
  const auto bundle = AreaBundle::open(dir_ / "aliased.txt");
  const auto run = [&](AreaWinner winner) {
    return detail::localize_in_bundle(*bundle, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, nullptr,
                                      {}, AreaSearch::kAll, winner);
  };
  const BundleLocalizeResult by_support = run(AreaWinner::kSupport);
  ASSERT_EQ(by_support.scored, (std::vector<int32_t>{0, 1, 2}));
  EXPECT_EQ(by_support.inliers, (std::vector<int32_t>{36, 30, 30}));
  EXPECT_EQ(by_support.support, (std::vector<int32_t>{36, 60, 60}));
  EXPECT_EQ(by_support.area, 1);  // ties on support and inliers: the smaller id
  EXPECT_LT(position_error(by_support.result.pose.cam_from_world, f.cam_from_world), 1e-6);
  const BundleLocalizeResult by_inliers = run(AreaWinner::kInliers);
  EXPECT_EQ(by_inliers.support, by_support.support);
  EXPECT_EQ(by_inliers.area, 0);
  EXPECT_NEAR(position_error(by_inliers.result.pose.cam_from_world, f.cam_from_world), 0.8, 1e-6);
  EXPECT_THROW(run(static_cast<AreaWinner>(5)), Error);
  // The winner's rival: the aliased pose explains its 36 keypoints with look-alikes the right pose
  // does not explain; the right pose's 60 keypoints are a rival to the aliased winner.
  EXPECT_EQ(by_support.rival_support, 36);
  EXPECT_EQ(by_inliers.rival_support, 60);
  // The bundle's evidence: the support as inliers, the rival as runner-up, every keypoint with a
  // match as offered; uncalibrated: the winning area's own answer.
  EXPECT_EQ(by_support.evidence.num_inliers, 60);
  EXPECT_EQ(by_support.evidence.runner_up_inliers, 36);
  EXPECT_EQ(by_support.evidence.num_keypoints, static_cast<int>(f.keypoints.size()));
  EXPECT_GE(by_support.evidence.num_correspondences, 60);
  EXPECT_FALSE(by_support.calibrated);
  EXPECT_EQ(by_support.confidence, -1.0);
  EXPECT_EQ(by_support.localized, by_support.result.localized);
  // localize_in_areas: the areas given, in that order, as a bundle search without a prior.
  const BundleLocalizeResult listed =
      detail::localize_in_areas(*bundle, {2, 0, 1}, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  EXPECT_EQ(listed.scored, (std::vector<int32_t>{2, 0, 1}));
  EXPECT_EQ(listed.support, (std::vector<int32_t>{60, 36, 60}));
  EXPECT_EQ(listed.area, 1);  // ties on support and inliers: the smaller id
  const BundleLocalizeResult alone =
      detail::localize_in_areas(*bundle, {0}, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  EXPECT_EQ(alone.area, 0);
  EXPECT_EQ(alone.support, std::vector<int32_t>{36});
  EXPECT_EQ(alone.rival_support, 0);
  EXPECT_THROW(
      detail::localize_in_areas(*bundle, {0, 3}, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam), Error);
  EXPECT_THROW(
      detail::localize_in_areas(*bundle, {1, 1}, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam), Error);
  // A calibrated bundle (index version 2): the confidence is the calibration's probability of the
  // bundle's evidence, localized at its operating point or at options.min_confidence.
  PoseCalibration c;
  c.weights = {1.0, 2.0, -3.0, 0.5, 0.25, 1.0, 0.0};
  c.bias = -2.0;
  c.threshold = 0.5;
  c.num_samples = 40;
  c.num_positive = 30;
  c.target_precision = 0.95;
  std::vector<BundleArea> areas = bundle->areas();
  test::write_test_bundle(dir_ / "calibrated.txt", 1.0, areas, &c);
  EXPECT_NE(read_file(dir_ / "calibrated.txt").find("\ncalibration "), std::string::npos);
  const auto calibrated = AreaBundle::open(dir_ / "calibrated.txt");
  ASSERT_TRUE(calibrated->calibrated());
  EXPECT_EQ(calibrated->calibration().weights, c.weights);
  EXPECT_EQ(calibrated->calibration().bias, c.bias);
  EXPECT_EQ(calibrated->calibration().threshold, c.threshold);
  EXPECT_EQ(calibrated->calibration().num_samples, 40);
  EXPECT_EQ(calibrated->calibration().num_positive, 30);
  EXPECT_EQ(calibrated->calibration().target_precision, 0.95);
  EXPECT_FALSE(bundle->calibrated());
  const BundleLocalizeResult cal = detail::localize_in_bundle(*calibrated, f.camera, f.keypoints, f.descriptors.data(),
                                                              f.gravity_in_cam, nullptr, {}, AreaSearch::kAll);
  ASSERT_EQ(cal.area, 1);
  EXPECT_TRUE(cal.calibrated);
  EXPECT_EQ(cal.confidence, c.probability(cal.evidence));
  EXPECT_EQ(cal.confidence_threshold, 0.5);
  EXPECT_EQ(cal.localized, cal.confidence >= 0.5);
  LocalizerOptions strict;
  strict.min_confidence = 1.0;
  const BundleLocalizeResult never = detail::localize_in_bundle(
      *calibrated, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, nullptr, strict, AreaSearch::kAll);
  EXPECT_EQ(never.confidence_threshold, 1.0);
  EXPECT_FALSE(never.localized);
  strict.min_confidence = 0.0;
  EXPECT_TRUE(detail::localize_in_bundle(*calibrated, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam,
                                         nullptr, strict, AreaSearch::kAll)
                  .localized);
  // The bundle localizer takes the rule from its options.
  BundleLocalizerOptions options;
  options.winner = AreaWinner::kInliers;
  EXPECT_EQ(BundleLocalizer(bundle, options)
                .localize(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, nullptr)
                .area,
            0);
  EXPECT_EQ(
      BundleLocalizer(bundle).localize(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, nullptr).area, 1);
}

// The same areas scored, supports, winner and pose in both results.
void expect_same_result(const BundleLocalizeResult& a, const BundleLocalizeResult& b, const std::string& what) {
  EXPECT_EQ(a.scored, b.scored) << what;
  EXPECT_EQ(a.inliers, b.inliers) << what;
  EXPECT_EQ(a.support, b.support) << what;
  EXPECT_EQ(a.rival_support, b.rival_support) << what;
  EXPECT_EQ(a.errors, b.errors) << what;
  EXPECT_EQ(a.area, b.area) << what;
  EXPECT_EQ(a.localized, b.localized) << what;
  EXPECT_EQ(a.result.pose.cam_from_world.translation, b.result.pose.cam_from_world.translation) << what;
  EXPECT_EQ(a.result.pose.inlier_mask, b.result.pose.inlier_mask) << what;
}

// A calibration whose probability is sigmoid(bias) for every pose with an inlier: bias +8 accepts
// every pose at the threshold 0.5, bias -8 none.
PoseCalibration constant_calibration(double bias) {
  PoseCalibration c;
  c.bias = bias;
  c.threshold = 0.5;
  return c;
}

TEST_F(AreaBundleTest, NearestFirstStopsAtTheFirstCalibratedLocalizedArea) {
  const test::TestWorld world = test::make_test_world(101, 60, 140, 21);
  std::vector<Eigen::Vector3d> far_positions = test::make_test_world(101, 60, 140, 99).positions;
  for (auto& p : far_positions) p += Eigen::Vector3d(50, 0, 0);
  const test::TestFrame& f = world.frame;
  // Area 0: the far model, cell x >= 25; area 1: the frame's own model, cell x < 25. Each as an
  // uncalibrated model, one whose calibration accepts every pose and one that accepts none.
  const auto model = [](ModelData d, std::optional<double> bias) {
    if (bias) d.calibration = constant_calibration(*bias);
    return std::make_shared<const Model>(std::move(d));
  };
  const ModelData own_data = test::make_code_model_data(world.positions);
  const ModelData far_data = test::make_code_model_data(far_positions, 7);
  const auto localize = [&](const std::shared_ptr<const Model>& m) {
    return Localizer(m).localize(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  };
  const LocalizeResult own = localize(model(own_data, std::nullopt));
  const LocalizeResult far = localize(model(far_data, std::nullopt));
  ASSERT_TRUE(own.pose.success);
  const int far_inliers = far.pose.success ? far.pose.num_inliers : 0;
  // Under kAll the pose explaining most keypoints wins (AreaWinner::kSupport); the far area's
  // matches are look-alikes of other landmarks, so that is the own area's unless the far one has as
  // many inliers (checked below on the supports).
  const int32_t all_winner = far.pose.success && far_inliers >= own.pose.num_inliers ? 0 : 1;
  int case_id = 0;
  // (Each case writes its own area files: a bundle reads an area on first use.)
  const auto run_with = [&](std::optional<double> own_bias, std::optional<double> far_bias, const Eigen::Vector3d* at,
                            AreaSearch search) {
    const fs::path folder = dir_ / ("case-" + std::to_string(case_id++));
    fs::create_directories(folder);
    test::write_test_bundle(folder / "bundle.txt", 1.0,
                            {add(*model(far_data, far_bias), 0, 25.0, kInf, folder),
                             add(*model(own_data, own_bias), 1, -kInf, 25.0, folder)});
    const auto two = AreaBundle::open(folder / "bundle.txt");
    PositionPrior prior;
    if (at != nullptr) prior.position = *at;
    prior.radius = 30.0;  // both areas selected
    return detail::localize_in_bundle(*two, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam,
                                      at != nullptr ? &prior : nullptr, {}, search);
  };
  const auto run = [&](std::optional<double> own_bias, std::optional<double> far_bias, const Eigen::Vector3d& at,
                       AreaSearch search) { return run_with(own_bias, far_bias, &at, search); };
  const Eigen::Vector3d in_own(0, 0, 0), in_far(30, 0, 0);
  // The prior in the own area's cell, its calibration accepting: it is scored first and wins; the
  // far area is not scored.
  const BundleLocalizeResult near = run(8.0, 8.0, in_own, AreaSearch::kNearestFirst);
  EXPECT_EQ(near.selected, 2);
  EXPECT_EQ(near.scored, std::vector<int32_t>{1});
  EXPECT_EQ(near.area, 1);
  EXPECT_EQ(near.result.pose.num_inliers, own.pose.num_inliers);
  EXPECT_EQ(near.result.pose.cam_from_world.translation, own.pose.cam_from_world.translation);
  // kAll scores both, in id order.
  const BundleLocalizeResult all = run(8.0, 8.0, in_own, AreaSearch::kAll);
  EXPECT_EQ(all.scored, (std::vector<int32_t>{0, 1}));
  EXPECT_EQ(all.inliers, (std::vector<int32_t>{far_inliers, own.pose.num_inliers}));
  EXPECT_EQ(all.area, all_winner);
  ASSERT_EQ(all.support.size(), 2u);
  EXPECT_GT(all.support[1], all.support[0]);
  EXPECT_GE(all.support[1], own.pose.num_inliers);
  // The prior in the far cell: the far area first. Its calibration rejecting: the own area is
  // scored too and kAll's rule decides; accepting (with a pose): the far area wins alone.
  const BundleLocalizeResult far_rejects = run(8.0, -8.0, in_far, AreaSearch::kNearestFirst);
  EXPECT_EQ(far_rejects.scored, (std::vector<int32_t>{0, 1}));
  EXPECT_EQ(far_rejects.area, all_winner);
  const BundleLocalizeResult far_accepts = run(8.0, 8.0, in_far, AreaSearch::kNearestFirst);
  const std::vector<int32_t> want = far.pose.success ? std::vector<int32_t>{0} : std::vector<int32_t>{0, 1};
  EXPECT_EQ(far_accepts.scored, want);
  EXPECT_EQ(far_accepts.area, far.pose.success ? 0 : 1);
  // Uncalibrated models never stop the search (a pose's inlier count alone is not trusted): every
  // selected area is scored, nearest first, and kAll's rule decides.
  const BundleLocalizeResult uncalibrated = run(std::nullopt, std::nullopt, in_own, AreaSearch::kNearestFirst);
  EXPECT_EQ(uncalibrated.scored, (std::vector<int32_t>{1, 0}));
  EXPECT_EQ(uncalibrated.area, all_winner);
  // Without a prior: kAll's search whatever the option.
  const BundleLocalizeResult none = run_with(8.0, 8.0, nullptr, AreaSearch::kNearestFirst);
  EXPECT_EQ(none.scored, (std::vector<int32_t>{0, 1}));
  EXPECT_EQ(none.area, all_winner);
  EXPECT_THROW(run(8.0, 8.0, in_own, static_cast<AreaSearch>(7)), Error);

  // A calibration that saw no wrong pose (it reports every pose) stops nothing: the areas' own, and
  // the bundle's; a bundle calibration that saw wrong poses stops at the first localized verdict.
  PoseCalibration all_right = constant_calibration(8.0);
  all_right.num_samples = all_right.num_positive = 20;
  ASSERT_TRUE(all_right.saw_no_wrong_pose());
  ModelData own_all_right = own_data, far_all_right = far_data;
  own_all_right.calibration = far_all_right.calibration = all_right;
  PoseCalibration discriminating = all_right;
  discriminating.num_positive = 15;
  const std::vector<const PoseCalibration*> bundle_calibrations = {nullptr, &all_right, &discriminating};
  for (const PoseCalibration* bundle_calibration : bundle_calibrations) {
    const fs::path folder = dir_ / ("case-" + std::to_string(case_id++));
    fs::create_directories(folder);
    test::write_test_bundle(
        folder / "bundle.txt", 1.0,
        {add(Model(far_all_right), 0, 25.0, kInf, folder), add(Model(own_all_right), 1, -kInf, 25.0, folder)},
        bundle_calibration);
    const auto two = AreaBundle::open(folder / "bundle.txt");
    PositionPrior prior;
    prior.position = in_own;
    prior.radius = 30.0;
    const BundleLocalizeResult r = detail::localize_in_bundle(*two, f.camera, f.keypoints, f.descriptors.data(),
                                                              f.gravity_in_cam, &prior, {}, AreaSearch::kNearestFirst);
    const bool stops = bundle_calibration == &discriminating;
    EXPECT_EQ(r.scored, stops ? std::vector<int32_t>{1} : (std::vector<int32_t>{1, 0})) << case_id;
    EXPECT_EQ(r.area, stops ? 1 : all_winner) << case_id;
  }
}

// Any number of area threads gives the one-thread result, the nearest-first stop included (the
// areas a wave scores after the stopping one are dropped).
TEST_F(AreaBundleTest, AreaThreadsGiveTheOneThreadResult) {
  const test::TestWorld world = test::make_test_world(101, 60, 140, 21);
  const test::TestFrame& f = world.frame;
  // Five areas along x, cells [id, id + 1) (the ends open): copies of the frame's model with every
  // landmark moved 0.3 m a step (look-alike poses); area 2 the true one, calibrated to accept
  // every pose; area 3's file damaged.
  std::vector<BundleArea> areas;
  for (int32_t id = 0; id < 5; ++id) {
    ModelData d = test::make_code_model_data(world.positions);
    for (auto& p : d.class_position) p += Eigen::Vector3d(0.3 * (id - 2), 0, 0);
    if (id == 2) d.calibration = constant_calibration(8.0);
    areas.push_back(add(Model(std::move(d)), id, id == 0 ? -kInf : id, id == 4 ? kInf : id + 1.0));
  }
  test::write_test_bundle(dir_ / "five.txt", 1.0, areas);
  std::string image = read_file(dir_ / "area-3.lbm");
  image[image.size() / 2] ^= 0x10;
  write_file_atomically(dir_ / "area-3.lbm", image);
  PositionPrior prior;
  prior.position = Eigen::Vector3d(0.5, 0, 0);  // nearest first: areas 0, 1, 2 (stops), 3, 4
  prior.radius = 10.0;
  for (const PositionPrior* p :
       {static_cast<const PositionPrior*>(&prior), static_cast<const PositionPrior*>(nullptr)}) {
    for (AreaSearch search : {AreaSearch::kNearestFirst, AreaSearch::kAll}) {
      const auto run = [&](int threads) {
        const auto bundle = AreaBundle::open(dir_ / "five.txt");
        return detail::localize_in_bundle(*bundle, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, p, {},
                                          search, AreaWinner::kSupport, threads);
      };
      const BundleLocalizeResult one = run(1);
      if (p != nullptr && search == AreaSearch::kNearestFirst) {
        EXPECT_EQ(one.scored, (std::vector<int32_t>{0, 1, 2}));
        EXPECT_EQ(one.area, 2);
      } else {
        EXPECT_EQ(one.scored.size(), 4u);  // every area but the damaged one
        EXPECT_EQ(one.errors.size(), 1u);
      }
      for (int threads : {2, 3, 5, 8}) {
        const BundleLocalizeResult many = run(threads);
        expect_same_result(many, one, "threads " + std::to_string(threads) + (p ? " prior" : " no prior"));
      }
    }
  }
  // A calibrated bundle stops nearest first as soon as its verdict over the areas scored so far is
  // localized (the areas' own calibrations no longer stop it): accepting every pose, after the
  // nearest area; accepting none, never. The same for any thread count.
  for (double bias : {50.0, -50.0}) {
    PoseCalibration c;
    c.bias = bias;
    c.threshold = 0.5;
    test::write_test_bundle(dir_ / "five_cal.txt", 1.0, areas, &c);
    for (int threads : {1, 3}) {
      const auto calibrated = AreaBundle::open(dir_ / "five_cal.txt");
      const BundleLocalizeResult r =
          detail::localize_in_bundle(*calibrated, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, &prior,
                                     {}, AreaSearch::kNearestFirst, AreaWinner::kSupport, threads);
      if (bias > 0) {
        EXPECT_EQ(r.scored, std::vector<int32_t>{0}) << threads;
        EXPECT_EQ(r.area, 0);
        EXPECT_TRUE(r.localized);
      } else {
        EXPECT_EQ(r.scored, (std::vector<int32_t>{0, 1, 2, 4})) << threads;  // area 3 is damaged
        EXPECT_FALSE(r.localized);
        EXPECT_EQ(r.area, detail::localize_in_bundle(*calibrated, f.camera, f.keypoints, f.descriptors.data(),
                                                     f.gravity_in_cam, &prior, {}, AreaSearch::kAll)
                              .area);
      }
    }
  }
  const auto bundle = AreaBundle::open(dir_ / "five.txt");
  for (int bad : {0, -1, 257}) {
    EXPECT_THROW(detail::localize_in_bundle(*bundle, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam,
                                            nullptr, {}, AreaSearch::kAll, AreaWinner::kSupport, bad),
                 Error)
        << bad;
    BundleLocalizerOptions options;
    options.area_threads = bad;
    EXPECT_THROW(options.check(), Error) << bad;
  }
}

TEST_F(AreaBundleTest, TrackingUsesTheLastPoseAsThePriorAndRelocalizesWithoutOne) {
  const NearAndFar n = near_and_far();
  const std::shared_ptr<const Model>& model = n.model;
  const Model& far_model = *n.far_model;
  const test::TestFrame& f = n.world.frame;
  const Eigen::Vector3d centre = f.cam_from_world.center();
  test::write_test_bundle(dir_ / "two.txt", 1.0, {add(far_model, 0, 25.0, kInf), add(*model, 1, -kInf, 25.0)});
  BundleLocalizerOptions options;
  options.tracking_radius = 2.0;
  BundleLocalizer localizer(AreaBundle::open(dir_ / "two.txt"), options);
  EXPECT_FALSE(localizer.last_position().has_value());
  // First frame: no last pose, every area.
  const BundleLocalizeResult first = localizer.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  EXPECT_FALSE(first.prior_used);
  EXPECT_EQ(first.scored, (std::vector<int32_t>{0, 1}));
  EXPECT_EQ(first.loaded, 2);
  ASSERT_EQ(first.area, 1);
  ASSERT_TRUE(localizer.last_position().has_value());
  EXPECT_LT((*localizer.last_position() - centre).norm(), 0.05);
  // Next frame: the last pose selects only the frame's own area; it is loaded already.
  const BundleLocalizeResult next = localizer.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  EXPECT_TRUE(next.prior_used);
  EXPECT_EQ(next.selected, 1);
  EXPECT_EQ(next.scored, std::vector<int32_t>{1});
  EXPECT_EQ(next.loaded, 0);
  EXPECT_EQ(next.area, 1);
  EXPECT_EQ(next.result.pose.num_inliers, first.result.pose.num_inliers);
  // The same as localize() with that prior.
  PositionPrior prior;
  prior.position = *localizer.last_position();
  prior.radius = 2.0;
  const BundleLocalizeResult direct =
      localizer.localize(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, &prior);
  EXPECT_EQ(direct.scored, next.scored);
  EXPECT_EQ(direct.result.pose.inlier_mask, next.result.pose.inlier_mask);
  localizer.reset_tracking();
  EXPECT_FALSE(localizer.last_position().has_value());

  // The frame's own area sits where the last pose is not: the prior's area (missing) gives no pose,
  // so track() relocalizes in every area, reporting the missing one once.
  test::write_test_bundle(dir_ / "swapped.txt", 1.0, {add(*model, 0, 25.0, kInf), add(far_model, 1, -kInf, 25.0)});
  fs::remove(dir_ / "area-1.lbm");
  BundleLocalizer swapped(AreaBundle::open(dir_ / "swapped.txt"), options);
  const BundleLocalizeResult a = swapped.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  ASSERT_EQ(a.area, 0);
  EXPECT_EQ(a.errors.size(), 1u);
  const BundleLocalizeResult b = swapped.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  EXPECT_FALSE(b.prior_used);  // the tracked prior (area 1 only) failed: relocalized
  EXPECT_EQ(b.area, 0);
  ASSERT_EQ(b.errors.size(), 1u);
  EXPECT_NE(b.errors[0].find("area 1 (area-1.lbm)"), std::string::npos) << b.errors[0];
  // Without relocalization the tracked frame fails and the last pose is kept.
  options.relocalize_without_prior = false;
  BundleLocalizer strict(AreaBundle::open(dir_ / "swapped.txt"), options);
  ASSERT_EQ(strict.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam).area, 0);
  const BundleLocalizeResult c = strict.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  EXPECT_TRUE(c.prior_used);
  EXPECT_EQ(c.area, -1);
  EXPECT_TRUE(c.scored.empty());
  EXPECT_TRUE(strict.last_position().has_value());
  // A calibrated bundle tracks from the poses it reports localized only: one that trusts no pose
  // relocalizes every frame and keeps no last pose; one that trusts every pose tracks.
  options.relocalize_without_prior = true;
  for (double bias : {-50.0, 50.0}) {
    const fs::path folder = dir_ / (bias > 0 ? "trusting" : "distrusting");
    fs::create_directories(folder);
    PoseCalibration constant;
    constant.bias = bias;
    constant.threshold = 0.5;
    test::write_test_bundle(folder / "bundle.txt", 1.0,
                            {add(far_model, 0, 25.0, kInf, folder), add(*model, 1, -kInf, 25.0, folder)}, &constant);
    BundleLocalizer calibrated(AreaBundle::open(folder / "bundle.txt"), options);
    const BundleLocalizeResult one = calibrated.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
    const BundleLocalizeResult two = calibrated.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
    EXPECT_EQ(one.area, 1) << bias;
    EXPECT_EQ(two.area, 1) << bias;
    EXPECT_EQ(two.localized, bias > 0);
    EXPECT_FALSE(one.prior_used) << bias;
    EXPECT_EQ(two.prior_used, bias > 0);
    EXPECT_EQ(calibrated.last_position().has_value(), bias > 0);
  }
  options.tracking_radius = -1.0;
  EXPECT_THROW(BundleLocalizer(AreaBundle::open(dir_ / "two.txt"), options), Error);
  EXPECT_THROW(BundleLocalizer(nullptr), Error);
}

// AreaSearch::kWinnersView: nearest area first, then the areas that see most of the current
// winning pose's view (an area that cannot load counts 0), the same result on any area threads.
TEST_F(AreaBundleTest, WinnersViewScoresTheAreasTheWinningPoseSeesNextOnAnyThreads) {
  const test::TestWorld world = test::make_test_world(101, 60, 140, 21);
  const test::TestFrame& f = world.frame;
  write_tracking_bundle(world);
  // The tracking bundle plus area 4, damaged, in area 3's cell (1 m away, like areas 1 and 3).
  std::vector<BundleArea> areas = AreaBundle::open(dir_ / "track.txt")->areas();
  BundleArea damaged = areas[1];
  damaged.id = 4;
  damaged.file = "area-4.lbm";
  damaged.cell_lo = areas[3].cell_lo;
  damaged.cell_hi = areas[3].cell_hi;
  std::string image = read_file(dir_ / "area-1.lbm");
  image[image.size() / 2] ^= 0x10;
  write_file_atomically(dir_ / "area-4.lbm", image);
  areas.push_back(damaged);
  test::write_test_bundle(dir_ / "view.txt", 50.0, areas);
  PositionPrior prior;
  prior.position = f.cam_from_world.center();
  prior.radius = 0.5;  // every area (reach 50 m)
  const auto run = [&](AreaSearch search, int threads) {
    const auto bundle = AreaBundle::open(dir_ / "view.txt");
    return detail::localize_in_bundle(*bundle, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, &prior,
                                      {}, search, AreaWinner::kSupport, threads);
  };
  // Uncalibrated: nothing stops the search, so the order shows. Nearest first: area 0 (its cell
  // holds the prior), then 1, 3 and 4 (1 m; by id), then 2 (2 m).
  const BundleLocalizeResult nearest = run(AreaSearch::kNearestFirst, 1);
  EXPECT_EQ(nearest.scored, (std::vector<int32_t>{0, 1, 3, 2}));
  ASSERT_EQ(nearest.errors.size(), 1u);
  EXPECT_NE(nearest.errors[0].find("area 4"), std::string::npos) << nearest.errors[0];
  // By the winner's view: area 0's look-alike pose (3 m behind the camera) sees all 60 landmarks
  // of area 1, 20 of area 2 and none of 3 (4 cannot load: 0); then area 1's pose wins, which sees
  // 20 of area 2 and none of 3 and 4, which go by distance and id.
  const BundleLocalizeResult view = run(AreaSearch::kWinnersView, 1);
  EXPECT_EQ(view.scored, (std::vector<int32_t>{0, 1, 2, 3}));
  EXPECT_EQ(view.errors, nearest.errors);
  EXPECT_EQ(view.area, 1);
  EXPECT_EQ(view.area, nearest.area);
  EXPECT_EQ(view.result.pose.cam_from_world.translation, nearest.result.pose.cam_from_world.translation);
  EXPECT_LT(position_error(view.result.pose.cam_from_world, f.cam_from_world), 1e-6);
  // Areas run ahead in a wave are used only where the one-thread order reaches them.
  for (int threads : {2, 3, 5}) {
    const BundleLocalizeResult many = run(AreaSearch::kWinnersView, threads);
    expect_same_result(many, view, "threads " + std::to_string(threads));
  }
  // A calibrated bundle that accepts every pose stops after the nearest area, as nearest first does.
  PoseCalibration accept;
  accept.bias = 50.0;
  accept.threshold = 0.5;
  test::write_test_bundle(dir_ / "view.txt", 50.0, areas, &accept);
  for (int threads : {1, 2}) EXPECT_EQ(run(AreaSearch::kWinnersView, threads).scored, std::vector<int32_t>{0});
  // Without a prior every area is scored in id order (kAll), whatever the search.
  const auto bundle = AreaBundle::open(dir_ / "view.txt");
  EXPECT_EQ(detail::localize_in_bundle(*bundle, f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, nullptr,
                                       {}, AreaSearch::kWinnersView)
                .scored,
            (std::vector<int32_t>{0, 1, 2, 3}));
  BundleLocalizerOptions options;
  options.search = AreaSearch::kWinnersView;
  EXPECT_NO_THROW(options.check());
  options.search = static_cast<AreaSearch>(3);
  EXPECT_THROW(options.check(), Error);
}

TEST_F(AreaBundleTest, TrackingScoresTheAreasTheLastPoseSeesFirstAndStopsAtTheMotionGate) {
  const test::TestWorld world = test::make_test_world(101, 60, 140, 21);
  const test::TestFrame& f = world.frame;
  const std::vector<int32_t> seen = frame_classes(f);
  ASSERT_EQ(seen.size(), 60u);
  Rng rng(23);
  const auto area_model = [&](size_t count, const Eigen::Vector3d& offset) {
    return AreaBundleTest::area_model(world, seen, rng, 0, count, offset);
  };
  const Eigen::Vector3d centre = f.cam_from_world.center();
  const Eigen::Vector3d axis = f.cam_from_world.rotation.inverse() * Eigen::Vector3d::UnitZ();  // optical axis
  const double x = centre.x();
  write_tracking_bundle(world);
  const auto bundle = AreaBundle::open(dir_ / "track.txt");
  // What the camera sees of each area (every landmark is sampled: fewer than kViewSample).
  EXPECT_EQ(bundle->visible_landmarks(0, f.camera, f.cam_from_world), 45);
  EXPECT_EQ(bundle->visible_landmarks(1, f.camera, f.cam_from_world), 60);
  EXPECT_EQ(bundle->visible_landmarks(2, f.camera, f.cam_from_world), 20);
  EXPECT_EQ(bundle->visible_landmarks(3, f.camera, f.cam_from_world), 0);
  // The sample outlives the area's model, and a missing area fails as model() does.
  bundle->release_except({});
  EXPECT_EQ(bundle->visible_landmarks(1, f.camera, f.cam_from_world), 60);
  EXPECT_FALSE(bundle->loaded(1));
  EXPECT_THROW(bundle->visible_landmarks(4, f.camera, f.cam_from_world), Error);

  {
    // (On area threads: TrackingOnAreaThreadsGivesTheOneThreadResult.)
    BundleLocalizerOptions options;
    options.tracking_radius = 1.0;
    options.tracking_areas = 1;
    BundleLocalizer localizer(bundle, options);
    const auto track = [&] { return localizer.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam); };
    // The last pose known: the area that sees most of its view first; its pose lies within the gate.
    localizer.set_last_pose(f.cam_from_world);
    const BundleLocalizeResult seen_first = track();
    EXPECT_TRUE(seen_first.prior_used);
    EXPECT_EQ(seen_first.selected, 4);
    EXPECT_EQ(seen_first.scored, std::vector<int32_t>{1});
    EXPECT_EQ(seen_first.area, 1);
    EXPECT_TRUE(seen_first.tracked);
    EXPECT_EQ(seen_first.localized, seen_first.result.localized);  // uncalibrated bundle: the area's own answer
    EXPECT_LT(position_error(*localizer.last_pose(), f.cam_from_world), 1e-6);
    // Two areas judged: the second (the look-alike) is scored too, and the support rule keeps the right pose.
    options.tracking_areas = 2;
    localizer.set_options(options);
    const BundleLocalizeResult two = track();
    EXPECT_EQ(two.scored, (std::vector<int32_t>{1, 0}));
    EXPECT_EQ(two.support, (std::vector<int32_t>{60, 45}));
    EXPECT_EQ(two.area, 1);
    EXPECT_TRUE(two.tracked);
    // Only a position known: the nearest cell first. The look-alike's pose lies 3 m away, outside
    // the gate; after the next area the right pose wins on support, inside it.
    options.tracking_areas = 1;
    localizer.set_options(options);
    localizer.set_last_position(centre);
    EXPECT_FALSE(localizer.last_pose().has_value());
    const BundleLocalizeResult by_distance = track();
    EXPECT_EQ(by_distance.scored, (std::vector<int32_t>{0, 1}));
    EXPECT_EQ(by_distance.inliers, (std::vector<int32_t>{45, 60}));
    EXPECT_EQ(by_distance.area, 1);
    EXPECT_TRUE(by_distance.tracked);
    ASSERT_TRUE(localizer.last_pose().has_value());
    EXPECT_LT(position_error(*localizer.last_pose(), f.cam_from_world), 1e-6);
    // A last pose 5 m away: no pose lies within the gate, every area is scored and the support
    // rule decides (not tracked; the uncalibrated bundle trusts the winner, which becomes the last pose).
    localizer.set_last_pose(
        Rigid3d(f.cam_from_world.rotation, f.cam_from_world.translation + Eigen::Vector3d(5, 0, 0)));
    const BundleLocalizeResult far = track();
    EXPECT_TRUE(far.prior_used);
    EXPECT_EQ(far.scored.size(), 4u);
    EXPECT_FALSE(far.tracked);
    EXPECT_EQ(far.area, 1);
    EXPECT_EQ(far.localized, far.result.localized);
    EXPECT_LT(position_error(*localizer.last_pose(), f.cam_from_world), 1e-6);
  }

  // A look-alike of all 60 landmarks 0.8 m to the side (inside the gate too): both poses explain
  // 60 keypoints, each the other's rival. Neither is a clear winner: not tracked.
  const Eigen::Vector3d side = f.cam_from_world.rotation.inverse() * Eigen::Vector3d::UnitX();
  test::write_test_bundle(
      dir_ / "tie.txt", 50.0,
      {add(*area_model(60, Eigen::Vector3d::Zero()), 0, -kInf, x), add(*area_model(60, 0.8 * side), 1, x, kInf)});
  {
    BundleLocalizerOptions options;
    options.tracking_radius = 1.0;
    BundleLocalizer localizer(AreaBundle::open(dir_ / "tie.txt"), options);
    localizer.set_last_pose(f.cam_from_world);
    const BundleLocalizeResult tie = localizer.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
    EXPECT_EQ(tie.scored.size(), 2u);
    EXPECT_EQ(tie.support, (std::vector<int32_t>{60, 60}));
    EXPECT_EQ(tie.rival_support, 60);
    EXPECT_EQ(tie.area, 0);  // ties: the smaller id
    EXPECT_FALSE(tie.tracked);
  }

  // The gate grows with the frames since the last pose (the camera moves at most tracking_radius a
  // frame): a calibration that trusts no pose and no relocalization, the last pose 1.5 m away. A
  // tracked pose becomes the last pose though the calibration does not trust it.
  PoseCalibration distrust;
  distrust.bias = -50.0;
  distrust.threshold = 0.5;
  const fs::path folder = dir_ / "distrusting";
  fs::create_directories(folder);
  test::write_test_bundle(folder / "bundle.txt", 50.0,
                          {add(*area_model(45, 3.0 * axis), 0, x - 1.0, x + 1.0, folder),
                           add(*area_model(60, Eigen::Vector3d::Zero()), 1, x + 1.0, x + 2.0, folder)},
                          &distrust);
  BundleLocalizerOptions options;
  options.tracking_radius = 1.0;
  options.relocalize_without_prior = false;
  BundleLocalizer localizer(AreaBundle::open(folder / "bundle.txt"), options);
  const Rigid3d away(f.cam_from_world.rotation,
                     f.cam_from_world.translation + f.cam_from_world.rotation * Eigen::Vector3d(1.5, 0, 0));
  ASSERT_NEAR((away.center() - centre).norm(), 1.5, 1e-9);
  localizer.set_last_pose(away);
  const auto track = [&] { return localizer.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam); };
  const BundleLocalizeResult first = track();  // gate 1 m: the right pose lies 1.5 m away
  EXPECT_FALSE(first.tracked);
  EXPECT_FALSE(first.localized);
  EXPECT_EQ(first.area, 1);
  EXPECT_LT((localizer.last_pose()->center() - away.center()).norm(), 1e-9);  // kept
  const BundleLocalizeResult second = track();                                // gate 2 m
  EXPECT_TRUE(second.tracked);
  EXPECT_FALSE(second.localized);  // the calibration's verdict, apart from the gate
  EXPECT_LT(second.confidence, 0.5);
  EXPECT_LT(position_error(*localizer.last_pose(), f.cam_from_world), 1e-6);

  // A relocalized winner inside the gate is tracked too: the right area's cell lies beyond the
  // tracked selection (reach 0.5 m), so only the look-alike is scored there (its pose 3 m away,
  // outside the gate) and the distrusting calibration sends the frame to every area.
  const fs::path beyond = dir_ / "beyond";
  fs::create_directories(beyond);
  test::write_test_bundle(beyond / "bundle.txt", 0.5,
                          {add(*area_model(45, 3.0 * axis), 0, x - 1.0, x + 1.0, beyond),
                           add(*area_model(60, Eigen::Vector3d::Zero()), 1, x + 5.0, kInf, beyond)},
                          &distrust);
  options.relocalize_without_prior = true;
  BundleLocalizer relocalizing(AreaBundle::open(beyond / "bundle.txt"), options);
  relocalizing.set_last_pose(f.cam_from_world);
  const BundleLocalizeResult relocalized =
      relocalizing.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  EXPECT_FALSE(relocalized.prior_used);
  EXPECT_EQ(relocalized.scored, (std::vector<int32_t>{0, 1}));
  EXPECT_EQ(relocalized.area, 1);
  EXPECT_TRUE(relocalized.tracked);
  EXPECT_FALSE(relocalized.localized);
  // A relocalization prior (e.g. a GPS fix) restricts a relocalization to the areas it selects:
  // here the look-alike's cell only; without one, every area.
  BundleLocalizer fresh(AreaBundle::open(beyond / "bundle.txt"), options);
  PositionPrior fix;
  fix.position = centre;
  fix.radius = 0.1;
  const BundleLocalizeResult restricted =
      fresh.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam, &fix);
  EXPECT_FALSE(restricted.prior_used);
  EXPECT_EQ(restricted.scored, std::vector<int32_t>{0});
  EXPECT_FALSE(fresh.last_pose().has_value());  // distrusted, and no last pose to gate it
  EXPECT_EQ(fresh.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam).scored,
            (std::vector<int32_t>{0, 1}));

  options.tracking_areas = 0;
  EXPECT_THROW(options.check(), Error);
  EXPECT_THROW(localizer.set_options(options), Error);
  options.tracking_areas = 257;
  EXPECT_THROW(options.check(), Error);
}

// With a walk calibration in the bundle, track()'s `localized` is the walk's verdict: poses that
// continue the walk are reported on support the frame rule alone refuses, a pose that jumps 1.5 m
// is refused although the frame rule reports it, and without the walk calibration the same frames
// get the frame rule's verdicts.
TEST_F(AreaBundleTest, TrackingWithAWalkCalibrationReportsTheWalkAndRefusesAJump) {
  const test::TestWorld world = test::make_test_world(101, 60, 140, 21);
  const Model model(test::make_code_model_data(world.positions));
  const PoseCalibration frame = test::walk_test_frame_calibration();
  const WalkCalibration walk = test::walk_test_walk_calibration();
  BundleIndex index;
  index.reach = 50.0;
  index.map_fingerprint = test::kTestMapFingerprint;
  index.areas = {add(model, 0, -kInf, kInf)};
  index.calibration = frame;
  index.walk_calibration = walk;
  write_bundle_index(dir_ / "walk.txt", index);
  EXPECT_NE(read_file(dir_ / "walk.txt").find("lmb-bundle 4\n"), std::string::npos);
  const auto bundle = AreaBundle::open(dir_ / "walk.txt");
  ASSERT_TRUE(bundle->walk_calibration().has_value());
  const WalkCalibration& read = *bundle->walk_calibration();
  EXPECT_EQ(read.weights, walk.weights);
  EXPECT_EQ(read.agreement_step_deg, walk.agreement_step_deg);
  EXPECT_EQ(read.translation_scale_m, walk.translation_scale_m);
  EXPECT_EQ(read.adds, true);
  index.walk_calibration->adds = false;
  write_bundle_index(dir_ / "agreement.txt", index);
  EXPECT_FALSE(AreaBundle::open(dir_ / "agreement.txt")->walk_calibration()->adds);
  // A walk calibration without the bundle's calibration is refused.
  BundleIndex bad = index;
  bad.calibration.reset();
  EXPECT_THROW(write_bundle_index(dir_ / "bad.txt", bad), Error);
  index.walk_calibration.reset();
  write_bundle_index(dir_ / "frames.txt", index);

  const std::vector<test::TestFrame> frames = test::walk_test_frames(world);
  ASSERT_EQ(frames.back().keypoints.size(), world.frame.keypoints.size());
  BundleLocalizerOptions options;
  options.tracking_radius = 1.0;
  std::vector<BundleLocalizeResult> walked, alone;
  BundleLocalizer walking(bundle, options);
  BundleLocalizer framing(AreaBundle::open(dir_ / "frames.txt"), options);
  for (const test::TestFrame& f : frames) {
    walked.push_back(walking.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam));
    alone.push_back(framing.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam));
  }
  for (size_t i = 0; i < frames.size(); ++i) {
    ASSERT_EQ(walked[i].area, 0) << i;
    EXPECT_LT(position_error(walked[i].result.pose.cam_from_world, frames[i].cam_from_world), 1e-3) << i;
    EXPECT_TRUE(walked[i].walk_judged) << i;
    EXPECT_FALSE(alone[i].walk_judged) << i;
    EXPECT_EQ(walked[i].frame_localized, alone[i].localized) << i;  // the frame rule's verdict, the same
    EXPECT_EQ(alone[i].frame_localized, alone[i].localized) << i;
    EXPECT_EQ(walked[i].localized, walked[i].walk.localized) << i;
  }
  EXPECT_TRUE(walked[0].localized);
  EXPECT_FALSE(walked[0].walk.continues);
  for (size_t i = 1; i <= 4; ++i) {
    EXPECT_FALSE(alone[i].localized) << i;  // 30 keypoints: the frame rule refuses
    EXPECT_TRUE(walked[i].walk.continues) << i;
    EXPECT_TRUE(walked[i].walk.by_walk) << i;
    EXPECT_TRUE(walked[i].localized) << i;
  }
  // The jump: the frame rule reports it; the walk's agreement refuses it.
  EXPECT_TRUE(alone[5].localized);
  EXPECT_TRUE(walked[5].frame_localized);
  EXPECT_TRUE(walked[5].walk.agreement_applies);
  EXPECT_FALSE(walked[5].walk.agrees);
  EXPECT_FALSE(walked[5].localized);
  // The refused pose did not become the last pose: the walk's last reported one is kept.
  ASSERT_TRUE(walking.last_pose().has_value());
  EXPECT_LT(position_error(*walking.last_pose(), frames[4].cam_from_world), 1e-3);
  // reset_tracking() forgets the walk: the same frame is judged as a first frame, by the frame rule.
  walking.reset_tracking();
  const test::TestFrame& f = frames.back();
  const BundleLocalizeResult fresh = walking.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
  EXPECT_FALSE(fresh.walk.compared);
  EXPECT_TRUE(fresh.localized);
}

// Tracking on area threads: the same areas scored, winners and gate verdicts as on one thread
// (the areas of a wave after the one that stops the search are dropped).
TEST_F(AreaBundleTest, TrackingOnAreaThreadsGivesTheOneThreadResult) {
  const test::TestWorld world = test::make_test_world(101, 60, 140, 21);
  const test::TestFrame& f = world.frame;
  write_tracking_bundle(world);
  const auto bundle = AreaBundle::open(dir_ / "track.txt");
  const auto run = [&](int threads, int areas) {
    BundleLocalizerOptions options;
    options.tracking_radius = 1.0;
    options.tracking_areas = areas;
    options.area_threads = threads;
    BundleLocalizer localizer(bundle, options);
    std::vector<BundleLocalizeResult> out;
    localizer.set_last_pose(f.cam_from_world);
    out.push_back(localizer.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam));
    localizer.set_last_position(f.cam_from_world.center());
    out.push_back(localizer.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam));
    localizer.set_last_pose(
        Rigid3d(f.cam_from_world.rotation, f.cam_from_world.translation + Eigen::Vector3d(5, 0, 0)));
    out.push_back(localizer.track(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam));
    return out;
  };
  for (int areas : {1, 2}) {
    const std::vector<BundleLocalizeResult> one = run(1, areas);
    for (int threads : {2, 3}) {
      const std::vector<BundleLocalizeResult> many = run(threads, areas);
      for (size_t i = 0; i < one.size(); ++i) {
        EXPECT_EQ(many[i].scored, one[i].scored) << threads << " " << areas << " " << i;
        EXPECT_EQ(many[i].support, one[i].support) << i;
        EXPECT_EQ(many[i].area, one[i].area) << i;
        EXPECT_EQ(many[i].tracked, one[i].tracked) << i;
        EXPECT_EQ(many[i].result.pose.inlier_mask, one[i].result.pose.inlier_mask) << i;
      }
    }
    EXPECT_TRUE(one[0].tracked && one[1].tracked && !one[2].tracked) << areas;
  }
}

}  // namespace
}  // namespace lmb
