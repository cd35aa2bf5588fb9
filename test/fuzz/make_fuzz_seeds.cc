// Writes the seed corpora of the fuzz targets, one folder per target under the given folder, with
// the project's own writers: make_fuzz_seeds <out_dir>. scripts/fuzz.sh runs it before fuzzing.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "common/feature_space.h"
#include "common/file_container.h"
#include "common/file_io.h"
#include "common/io/colmap_binary.h"
#include "common/io/colmap_model.h"
#include "common/io/gravity_file.h"
#include "common/io/map_h5.h"
#include "common/io/session_file.h"
#include "common/vocabulary.h"
#include "infer/area_bundle.h"
#include "infer/bundle_index.h"
#include "infer/model.h"
#include "test/common/io/test_maps.h"
#include "test/fuzz/fuzz_util.h"
#include "test/infer/test_models.h"
#include "train/areas/area_file.h"
#include "train/areas/area_split.h"
#include "train/boost/boost_model.h"
#include "train/boost/stump_learner.h"
#include "train/boost/synthetic_problem.h"
#include "train/boost/train_config.h"
#include "train/checkpoint/checkpoint_h5.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

void put(const fs::path& dir, const std::string& name, const std::string& bytes) {
  fs::create_directories(dir);
  fuzz::write_file(dir / name, bytes);
}

std::string as_string(const std::vector<uint8_t>& v) { return std::string(v.begin(), v.end()); }

// Two cameras, three images (2D points on two of them), two 3D points with tracks.
ColmapModel small_colmap_model() {
  ColmapModel m;
  Camera a;
  a.model = CameraModel::kSimpleRadial;
  a.width = 640;
  a.height = 480;
  a.params = {500, 320, 240, -0.05};
  Camera b;
  b.model = CameraModel::kOpenCV;
  b.width = 320;
  b.height = 240;
  b.params = {250, 251, 160, 120, -0.1, 0.01, 0.001, -0.001};
  m.cameras = {{1, a}, {4, b}};
  for (int i = 1; i <= 3; ++i) {
    ColmapImage im;
    im.image_id = i;
    im.camera_id = i == 2 ? 4 : 1;
    im.name = (i == 3 ? "query/" : "map/") + std::to_string(i) + ".png";
    im.cam_from_world.rotation =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * i, Eigen::Vector3d(0.1, 1, 0.2).normalized()));
    im.cam_from_world.translation = Eigen::Vector3d(0.5 * i, -0.25, 1.0);
    if (i < 3) {
      im.points2d = {{Eigen::Vector2d(10.5, 20.25), 7},
                     {Eigen::Vector2d(100, 50), ColmapPoint2D::kNoPoint3D},
                     {Eigen::Vector2d(30, 40.5), 9}};
    }
    m.images.push_back(im);
  }
  for (int64_t id : {7, 9}) {
    ColmapPoint3D p;
    p.point3d_id = id;
    p.xyz = Eigen::Vector3d(1.0 * id, 2.0, -3.5);
    p.rgb << 10, 200, static_cast<uint8_t>(id);
    p.error = 0.75;
    p.track = {{1, id == 7 ? 0 : 2}, {2, id == 7 ? 0 : 2}};
    m.points.push_back(p);
  }
  return m;
}

void make_seeds(const fs::path& out, const fs::path& scratch) {
  fs::create_directories(scratch);
  // model.lbm: the code model of the infer tests, with 3 and 40 classes.
  for (int classes : {3, 40}) {
    std::vector<Eigen::Vector3d> positions;
    for (int c = 0; c < classes; ++c) positions.emplace_back(c, 0.5 * c, 2.0);
    const Model model(test::make_code_model_data(positions));
    put(out / "model", "code_" + std::to_string(classes) + ".lbm", as_string(model.to_bytes()));
  }
  // vocab.lbv: the infer tests' 4-word vocabulary and a 16-word one of 64-byte words.
  {
    put(out / "vocabulary", "test.lbv",
        as_string(make_container(kVocabularyMagic, kVocabularyVersion, test::test_vocabulary().to_payload())));
    std::vector<uint8_t> words(16 * 64);
    for (size_t i = 0; i < words.size(); ++i) words[i] = static_cast<uint8_t>(i * 131 + 7);
    const Vocabulary brisk(64, words);
    put(out / "vocabulary", "brisk16.lbv",
        as_string(make_container(kVocabularyMagic, kVocabularyVersion, brisk.to_payload())));
  }
  // map.h5: the map_h5 tests' random map and an empty map.
  {
    write_map_h5(test::random_map(1), scratch / "map.h5");
    put(out / "map_h5", "random.h5", read_file(scratch / "map.h5"));
    LandmarkMap empty;
    empty.detector = "BRISK";
    empty.descriptor_bytes = 64;
    write_map_h5(empty, scratch / "empty.h5");
    put(out / "map_h5", "empty.h5", read_file(scratch / "empty.h5"));
  }
  // COLMAP text and binary: the same small model, with and without points3D.
  {
    const ColmapModel m = small_colmap_model();
    write_colmap_text(m, scratch / "text");
    write_colmap_binary(m, scratch / "bin");
    for (const char* ext : {"txt", "bin"}) {
      const fs::path dir = scratch / (std::string(ext) == "txt" ? "text" : "bin");
      const std::string cameras = read_file(dir / (std::string("cameras.") + ext));
      const std::string images = read_file(dir / (std::string("images.") + ext));
      const std::string points = read_file(dir / (std::string("points3D.") + ext));
      const fs::path target = out / (std::string(ext) == "txt" ? "colmap_text" : "colmap_binary");
      put(target, "model", fuzz::join_files({cameras, images, points}));
      put(target, "model_no_points", fuzz::join_files({cameras, images}));
    }
  }
  // TOML: the full default config and a short one.
  put(out / "train_config", "defaults.toml", train_config_toml(TrainConfig{}));
  put(out / "train_config", "short.toml",
      "# a short config\n[boost]\nnum_rounds = 50\nexclusion_radius = 0.25\nscreening_step = true\n"
      "[regions]\nnum_regions = 100\n[features]\nthreads = 2\n");
  // model.bin: a two-stump model in a map's feature space (3 regions, 4 words of 8 bytes) and in a
  // synthetic one.
  {
    BoostModel m;
    m.num_dims = 3 * 4 + 64;
    m.num_classes = 2;
    m.class_landmark = {4, 9};
    m.bias = {0.5, -0.25, 0.0};
    m.stumps.push_back({1, 4, 2.0, -1.0, {0, 2}});
    m.stumps.push_back({70, 0, -0.5, 0.25, {1}});
    LandmarkMap map = test::random_map(1);
    map.descriptor_bytes = 8;
    map.descriptors.assign(map.keypoints.size() * 8, 3);
    const FeatureSpace space =
        map_feature_space(ContextRegions(ContextRegionOptions{.num_regions = 3}), test::test_vocabulary(), map);
    save_trained_model(scratch / "model.bin", m, space);
    put(out / "trained_model", "map.bin", read_file(scratch / "model.bin"));
    m.num_dims = 80;
    save_trained_model(scratch / "synthetic.bin", m, synthetic_feature_space("synthetic:small", 80));
    put(out / "trained_model", "synthetic.bin", read_file(scratch / "synthetic.bin"));
  }
  // Gravity.
  write_gravity_file({{"map/1.png", Eigen::Vector3d(0, 1, 0)},
                      {"map/2.png", Eigen::Vector3d(0.1, 0.9, -0.2)},
                      {"query/3.png", Eigen::Vector3d(1e-3, 2.5, 1e3)}},
                     scratch / "gravity.txt");
  put(out / "gravity", "gravity.txt", read_file(scratch / "gravity.txt"));
  // Checkpoints of a small synthetic problem (8 classes) after 0 and 3 rounds.
  {
    SyntheticBoostOptions o;
    o.num_classes = 8;
    const SyntheticBoostProblem problem = make_synthetic_boost_problem(o);
    TrainConfig config;
    config.boost.num_rounds = 3;
    config.boost.dims_per_round = 16;
    SerialStumpLearner learner(problem.features, problem.set, config.boost);
    for (int32_t rounds : {0, 3}) {
      while (learner.rounds_done() < rounds) learner.run_round();
      Checkpoint ck;
      ck.rounds = rounds;
      ck.seed = config.boost.seed;
      ck.config = train_config_toml(config);
      ck.data = "synthetic:fuzz";
      ck.feature_space = synthetic_feature_space(ck.data, problem.features.num_dims);
      ck.state = learner.save_state();
      const fs::path path = scratch / ("ckpt-rounds" + std::to_string(rounds) + ".h5");
      write_checkpoint(path, ck);
      put(out / "checkpoint", path.filename().string(), read_file(path));
    }
  }
  // bundle.txt: the writer's version with 3 areas, without and with a calibration, and a version 1
  // index (older `lboost bundle`); each opens (checked here).
  {
    const double inf = std::numeric_limits<double>::infinity();
    BundleIndex index;
    index.reach = 5.0558576932189325;
    index.map_fingerprint = 0x0123456789abcdefULL;
    for (int32_t id = 0; id < 3; ++id) {
      BundleArea a;
      a.id = id;
      a.file = "area-" + std::to_string(id) + ".lbm";
      a.bytes = 6246098 + id;
      a.crc32 = 0x1a2b3c4du + static_cast<uint32_t>(id);
      a.landmarks = 6866 + id;
      a.first_landmark = 10 * id;
      a.last_landmark = 9120 + id;
      a.classes = 0xfedcba9876543210ULL + static_cast<uint64_t>(id);
      a.cell_lo = Eigen::Vector3d(id == 0 ? -inf : id - 0.5, -inf, -inf);
      a.cell_hi = Eigen::Vector3d(id == 2 ? inf : id + 0.5, inf, 2.5);
      index.areas.push_back(a);
    }
    write_bundle_index(scratch / "bundle.txt", index);
    put(out / "bundle_index", "three_areas.txt", read_file(scratch / "bundle.txt"));
    PoseCalibration c;
    for (size_t k = 0; k < c.weights.size(); ++k) c.weights[k] = 0.25 * static_cast<double>(k) - 0.5;
    c.bias = -2.5;
    c.threshold = 0.8;
    c.num_samples = 50;
    c.num_positive = 30;
    c.target_precision = 0.95;
    index.calibration = c;
    write_bundle_index(scratch / "bundle.txt", index);
    put(out / "bundle_index", "calibrated.txt", read_file(scratch / "bundle.txt"));
    put(out / "bundle_index", "version1.txt",
        "lmb-bundle 1\nreach 1.0\nareas 2\n"
        "area 0 file area-0.lbm bytes 10 crc32 0000abcd landmarks 3 cell -inf -inf -inf 0 inf inf\n"
        "area 1 file area-1.lbm bytes 12 crc32 ffffffff landmarks 4 cell 0 -inf -inf inf inf inf\n");
    for (const char* name : {"three_areas.txt", "calibrated.txt", "version1.txt"}) {
      AreaBundle::open(out / "bundle_index" / name);
    }
  }
  // Areas files: the split of the map_h5 tests' random map into areas of 2 landmarks, and one
  // area written by hand; each reads back (checked here).
  {
    const LandmarkMap map = test::random_map(1);
    AreaSplitOptions options;
    options.max_classes = 2;
    options.min_observations = 1;
    options.overlap = 0.5;
    AreaFile file;
    file.map_fingerprint = fingerprint_map(map);
    file.map_landmarks = static_cast<int64_t>(map.landmarks.size());
    file.split = split_map_into_areas(map, options);
    write_area_file(scratch / "areas.txt", file, "test::random_map(1)");
    put(out / "area_file", "random_map.txt", read_file(scratch / "areas.txt"));
    AreaFile one;
    one.map_fingerprint = 0x0123456789abcdefULL;
    one.map_landmarks = 10;
    one.split.options.max_classes = 4;
    one.split.options.min_observations = 2;
    one.split.options.overlap = 1.0;
    one.split.options.reach = 2.5;
    one.split.num_eligible = 4;
    Area a;
    a.landmarks = {1, 3, 4, 9};
    a.num_core = 4;
    a.bounds.lo = Eigen::Vector3d(0.0, -1.0, 0.5);
    a.bounds.hi = Eigen::Vector3d(1.0, 2.0, 3.0);
    one.split.areas = {a};
    write_area_file(scratch / "one_area.txt", one, "");
    put(out / "area_file", "one_area.txt", read_file(scratch / "one_area.txt"));
    for (const char* name : {"random_map.txt", "one_area.txt"}) read_area_file(out / "area_file" / name);
  }
  // Sessions files: four sessions of every kind from the writer, and one with comments and blank
  // lines; each reads back (checked here).
  {
    write_session_file({{"map", SessionKind::kMap},
                        {"map-2", SessionKind::kMap},
                        {"query_1", SessionKind::kQuery},
                        {"outside.a", SessionKind::kOutside}},
                       scratch / "sessions.txt");
    put(out / "session_file", "four.txt", read_file(scratch / "sessions.txt"));
    put(out / "session_file", "comments.txt", "# the sessions of a collection\n\nmap map\n# held out\nquery query\n");
    for (const char* name : {"four.txt", "comments.txt"}) read_session_file(out / "session_file" / name);
  }
}

}  // namespace
}  // namespace lmb

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <out_dir>\n", argv[0]);
    return 2;
  }
  const std::filesystem::path out = argv[1];
  try {
    lmb::make_seeds(out, out / ".scratch");
    std::filesystem::remove_all(out / ".scratch");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_fuzz_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
