// The input validation inventory (docs/input_validation.md), as a test: every row builds one bad
// input file, feeds it to the project's loader and expects lmb::Error with exactly the documented
// one-line message (the scratch folder shown as DIR). A second test checks that the document lists
// every row's message, so the table cannot drift from the code.
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <H5Cpp.h>
#include <gtest/gtest.h>

#include "common/error.h"
#include "common/feature_space.h"
#include "common/file_container.h"
#include "common/io/colmap_binary.h"
#include "common/io/colmap_model.h"
#include "common/io/gravity_file.h"
#include "common/io/map_h5.h"
#include "common/io/session_file.h"
#include "common/vocabulary.h"
#include "infer/area_bundle.h"
#include "infer/detail/model_format.h"
#include "infer/detail/scoring_index.h"
#include "infer/model.h"
#include "test/common/io/test_maps.h"
#include "test/infer/test_models.h"
#include "train/areas/area_file.h"
#include "train/boost/boost_model.h"
#include "train/boost/train_config.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

struct Row {
  std::string file;                               // the kind of input
  std::string defect;                             // what is wrong with it
  std::function<void(const fs::path& dir)> load;  // writes the bad input under dir and loads it
  std::string message;                            // the exact lmb::Error message, the scratch folder written as DIR
};

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::string as_string(const std::vector<uint8_t>& v) { return std::string(v.begin(), v.end()); }

// ---- model.lbm and vocab.lbv --------------------------------------------------------------

ModelData good_model_data() { return test::make_code_model_data({{0, 0, 2}, {1, 0, 2}, {0, 1, 3}}); }
std::string good_model_file() { return as_string(Model(good_model_data()).to_bytes()); }
// The writer refuses invalid models, so bad values are patched into a valid payload: `edit` marks a
// double field with kMark, then the payload's only copy of kMark is replaced by `value`
// (`dim_value`, when set, goes into the int32 stump dim written 5 bytes before a marked stump.a).
constexpr double kMark = 4242.4242;
std::string patched_model_file(const std::function<void(ModelData&)>& edit, double value,
                               std::optional<int32_t> dim_value = std::nullopt) {
  ModelData d = good_model_data();
  edit(d);
  std::string p = serialize_model_data(d);
  const std::string mark(reinterpret_cast<const char*>(&kMark), 8);
  const size_t at = p.find(mark);
  if (at == std::string::npos || p.find(mark, at + 1) != std::string::npos) throw std::logic_error("mark not unique");
  std::memcpy(p.data() + at, &value, 8);
  if (dim_value) std::memcpy(p.data() + at - 5, &*dim_value, 4);
  return as_string(make_container(kModelMagic, kModelVersionWithoutFusion, p));
}
// A valid payload with `edit` applied to its bytes.
std::string edited_model_file(const std::function<void(std::string&)>& edit) {
  std::string p = serialize_model_data(good_model_data());
  edit(p);
  return as_string(make_container(kModelMagic, kModelVersionWithoutFusion, p));
}
std::string good_vocab_file() {
  return as_string(make_container(kVocabularyMagic, kVocabularyVersion, test::test_vocabulary().to_payload()));
}

// Loads DIR/model.lbm holding `bytes`.
std::function<void(const fs::path&)> model_with(std::function<std::string()> bytes) {
  return [bytes](const fs::path& dir) {
    write_bytes(dir / "model.lbm", bytes());
    Model::load(dir / "model.lbm");
  };
}
std::function<void(const fs::path&)> vocab_with(std::function<std::string()> bytes) {
  return [bytes](const fs::path& dir) {
    write_bytes(dir / "vocab.lbv", bytes());
    Vocabulary::load(dir / "vocab.lbv");
  };
}

std::string with_byte(std::string s, size_t at, char value) {
  s[at] = value;
  return s;
}

// ---- bundle.txt -------------------------------------------------------------------------------

// Writes DIR/area-ID.lbm for each model and DIR/bundle.txt indexing them (write_bundle_index,
// version 3), then applies `edit` to the index's text and opens it; `then` (when set) uses it.
std::function<void(const fs::path&)> bundle_with(std::function<void(std::string&)> edit,
                                                 std::function<void(AreaBundle&)> then = {},
                                                 std::vector<ModelData> models = {good_model_data()}) {
  return [edit, then, models](const fs::path& dir) {
    std::vector<BundleArea> areas;
    for (size_t i = 0; i < models.size(); ++i) {
      const std::string file = "area-" + std::to_string(i) + ".lbm";
      const Model model(models[i]);
      const std::string image = as_string(model.to_bytes());
      write_bytes(dir / file, image);
      BundleArea a = describe_area(static_cast<int32_t>(i), file, image, model);
      a.cell_lo = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
      a.cell_hi = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
      a.cell_lo.x() = static_cast<double>(i);
      if (i + 1 < models.size()) a.cell_hi.x() = static_cast<double>(i + 1);
      areas.push_back(a);
    }
    test::write_test_bundle(dir / "bundle.txt", 1.0, areas);
    std::string text = read_bytes(dir / "bundle.txt");
    if (edit) edit(text);
    write_bytes(dir / "bundle.txt", text);
    const auto bundle = AreaBundle::open(dir / "bundle.txt");
    if (then) then(*bundle);
  };
}

// Replaces the first `from` in `text` by `to` (an edit of bundle_with).
std::function<void(std::string&)> replaced(const std::string& from, const std::string& to) {
  return [from, to](std::string& text) {
    const size_t at = text.find(from);
    if (at == std::string::npos) throw std::logic_error("no '" + from + "' in the index");
    text.replace(at, from.size(), to);
  };
}

// ---- map.h5 ---------------------------------------------------------------------------------

// Loads DIR/map.h5: test::random_map(3) edited by `edit` (applied to the open file).
std::function<void(const fs::path&)> map_edited(std::function<void(H5::H5File&)> edit) {
  return [edit](const fs::path& dir) {
    const fs::path path = dir / "map.h5";
    write_map_h5(test::random_map(3), path);
    {
      H5::H5File file(path.string(), H5F_ACC_RDWR);
      edit(file);
    }
    read_map_h5(path);
  };
}

// Sets element `index` of the double dataset `name`.
std::function<void(H5::H5File&)> set_double(const std::string& name, size_t index, double value) {
  return [=](H5::H5File& f) {
    H5::DataSet ds = f.openDataSet(name);
    hsize_t dims[2] = {0, 0};
    const int rank = ds.getSpace().getSimpleExtentDims(dims);
    std::vector<double> v(rank == 2 ? dims[0] * dims[1] : dims[0]);
    ds.read(v.data(), H5::PredType::NATIVE_DOUBLE);
    v.at(index) = value;
    ds.write(v.data(), H5::PredType::NATIVE_DOUBLE);
  };
}

// ---- COLMAP ---------------------------------------------------------------------------------

ColmapModel small_colmap() {
  ColmapModel m;
  Camera c;
  c.model = CameraModel::kPinhole;
  c.width = 640;
  c.height = 480;
  c.params = {500, 500, 320, 240};
  m.cameras = {{1, c}};
  for (int i = 1; i <= 2; ++i) {
    ColmapImage im;
    im.image_id = i;
    im.camera_id = 1;
    im.name = "im" + std::to_string(i) + ".png";
    im.cam_from_world.translation = Eigen::Vector3d(i, 0, 0);
    im.points2d = {{Eigen::Vector2d(10, 20), 5}};
    m.images.push_back(im);
  }
  ColmapPoint3D p;
  p.point3d_id = 5;
  p.xyz = Eigen::Vector3d(1, 2, 3);
  p.track = {{1, 0}, {2, 0}};
  m.points.push_back(p);
  return m;
}

// Writes small_colmap() as text into DIR/sparse, replaces `file` by `content`, reads the model.
std::function<void(const fs::path&)> colmap_text_with(const std::string& file, const std::string& content) {
  return [=](const fs::path& dir) {
    write_colmap_text(small_colmap(), dir / "sparse");
    write_bytes(dir / "sparse" / file, content);
    read_colmap_model(dir / "sparse");
  };
}

// Writes `edit`ed small_colmap() as binary into DIR/sparse, applies `bytes_edit` to `file`'s bytes,
// reads the model.
std::function<void(const fs::path&)> colmap_binary_with(std::function<void(ColmapModel&)> edit,
                                                        const std::string& file = "",
                                                        std::function<void(std::string&)> bytes_edit = {}) {
  return [=](const fs::path& dir) {
    ColmapModel m = small_colmap();
    if (edit) edit(m);
    write_colmap_binary(m, dir / "sparse");
    if (bytes_edit) {
      std::string b = read_bytes(dir / "sparse" / file);
      bytes_edit(b);
      write_bytes(dir / "sparse" / file, b);
    }
    read_colmap_model(dir / "sparse");
  };
}

// ---- gravity.txt and configs ----------------------------------------------------------------

std::function<void(const fs::path&)> gravity_with(const std::string& content) {
  return [=](const fs::path& dir) {
    write_bytes(dir / "gravity.txt", content);
    read_gravity_file(dir / "gravity.txt", small_colmap());
  };
}

std::function<void(const fs::path&)> sessions_with(const std::string& content) {
  return [=](const fs::path& dir) {
    write_bytes(dir / "sessions.txt", content);
    read_session_file(dir / "sessions.txt");
  };
}

// An areas file of one area of test::random_map(1)'s 6 landmarks, `edit`ed, read for that map.
std::function<void(const fs::path&)> areas_with(std::function<void(std::string&)> edit) {
  return [edit](const fs::path& dir) {
    const LandmarkMap map = test::random_map(1);
    AreaFile file;
    file.map_fingerprint = fingerprint_map(map);
    file.map_landmarks = static_cast<int64_t>(map.landmarks.size());
    file.split.options.reach = 2.0;
    file.split.num_eligible = file.map_landmarks;
    Area area;
    area.bounds.lo = Eigen::Vector3d::Zero();
    area.bounds.hi = Eigen::Vector3d::Ones();
    area.num_core = file.map_landmarks;
    area.landmarks = {0, 1, 2, 3, 4, 5};
    file.split.areas.push_back(area);
    std::string text = area_file_text(file, "");
    edit(text);
    write_bytes(dir / "areas.txt", text);
    read_area_landmarks(dir / "areas.txt", 0, map);
  };
}

std::function<void(const fs::path&)> config_with(const std::string& content) {
  return [=](const fs::path& dir) {
    write_bytes(dir / "train.toml", content);
    read_train_config(dir / "train.toml").check();
  };
}

std::vector<Row> rows() {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<Row> r;
  // model.lbm
  r.push_back({"model.lbm", "missing file", [](const fs::path& dir) { Model::load(dir / "model.lbm"); },
               "DIR/model.lbm: cannot open file: No such file or directory"});
  r.push_back({"model.lbm", "a folder",
               [](const fs::path& dir) {
                 fs::create_directories(dir / "model.lbm");
                 Model::load(dir / "model.lbm");
               },
               "DIR/model.lbm: is a folder, not a file"});
  r.push_back({"model.lbm", "empty file", model_with([] { return std::string(); }),
               "DIR/model.lbm: file too short (0 bytes) for a LMBMODEL header"});
  r.push_back({"model.lbm", "a vocabulary file instead", model_with(good_vocab_file),
               "DIR/model.lbm: not a LMBMODEL file (wrong magic)"});
  r.push_back({"model.lbm", "format version 6", model_with([] { return with_byte(good_model_file(), 8, 6); }),
               "DIR/model.lbm: format version 6 is not supported (this build reads versions 1 to 5)"});
  r.push_back({"model.lbm", "NaN pose calibration bias (format version 3)", model_with([nan] {
                 ModelData d = good_model_data();
                 PoseCalibration c;
                 c.bias = kMark;
                 c.threshold = 0.5;
                 d.calibration = c;
                 std::string p = serialize_model_data(d);
                 const std::string mark(reinterpret_cast<const char*>(&kMark), 8);
                 std::memcpy(p.data() + p.find(mark), &nan, 8);
                 return as_string(make_container(kModelMagic, kModelVersion, p));
               }),
               "DIR/model.lbm: pose calibration: bias is not finite"});
  r.push_back({"model.lbm", "truncated (last byte cut)", model_with([] {
                 std::string s = good_model_file();
                 s.pop_back();
                 return s;
               }),
               "DIR/model.lbm: truncated or padded: header says 2024 payload bytes, file has 2023"});
  r.push_back({"model.lbm", "one payload bit flipped", model_with([] {
                 std::string s = good_model_file();
                 s[s.size() - 5] ^= 0x10;
                 return s;
               }),
               "DIR/model.lbm: CRC mismatch (file is corrupt)"});
  r.push_back({"model.lbm", "payload cut behind a valid header", model_with([] {
                 const std::string p = serialize_model_data(good_model_data());
                 return as_string(make_container(kModelMagic, kModelVersionWithoutFusion, p.substr(0, p.size() / 2)));
               }),
               "DIR/model.lbm: stumps: corrupt count 46 exceeds the 682 bytes left"});
  r.push_back({"model.lbm", "a count of 2^60 (detector name)", model_with([] {
                 std::string p = serialize_model_data(good_model_data());
                 const uint64_t huge = uint64_t{1} << 60;
                 std::memcpy(p.data() + 1, &huge, 8);
                 return as_string(make_container(kModelMagic, kModelVersionWithoutFusion, p));
               }),
               "DIR/model.lbm: detector: corrupt count 1152921504606846976 exceeds the 2015 bytes left"});
  r.push_back({"model.lbm", "NaN landmark position", model_with([nan] {
                 return patched_model_file([](ModelData& d) { d.class_position[1].y() = kMark; }, nan);
               }),
               "DIR/model.lbm: class 1 has a non-finite position"});
  r.push_back({"model.lbm", "infinite stump value", model_with([] {
                 return patched_model_file([](ModelData& d) { d.stumps[2].a = kMark; },
                                           std::numeric_limits<double>::infinity());
               }),
               "DIR/model.lbm: stump 2: non-finite a or b"});
  r.push_back({"model.lbm", "stump on a dimension past the layout", model_with([] {
                 const int32_t num_dims = detail::layout_of(good_model_data()).num_dims();
                 return patched_model_file([](ModelData& d) { d.stumps[0].a = kMark; }, 2.0, num_dims);
               }),
               "DIR/model.lbm: stump 0: dim 76 outside [0, 76)"});
  r.push_back({"model.lbm", "class 3 (the background) in the last inverted list", model_with([] {
                 // The last list holds classes 0, 1, 2 as gaps 0, 1, 1: a last gap of 2 lists class 3.
                 return edited_model_file([](std::string& p) { p.back() = 2; });
               }),
               "DIR/model.lbm: inverted file word 3: corrupt id list: id 3 exceeds 2"});
  r.push_back({"model.lbm", "descriptor length differs from the vocabulary's", model_with([] {
                 // The int32 descriptor_bytes follows the archive's endianness byte and the detector name.
                 return edited_model_file([](std::string& p) { p[1 + 8 + 4] = 16; });
               }),
               "DIR/model.lbm: vocabulary has 8-byte words, descriptors have 16 bytes"});
  r.push_back({"model.lbm", "an empty context region (a crafted file)", model_with([] {
                 // Region 0's four floats follow the endianness byte, the detector name (8 + 4 bytes),
                 // descriptor_bytes, the region options (4 + 8 + 4 x 8 bytes) and the region count.
                 return edited_model_file([](std::string& p) { std::memset(p.data() + 1 + 12 + 4 + 44 + 8, 0, 16); });
               }),
               "DIR/model.lbm: regions: region 0 is empty ([0, 0) x [0, 0))"});
  // model.bin (the trainer's output)
  r.push_back({"model.bin", "format version 1 (an older lboost: no feature-space record)",
               [](const fs::path& dir) {
                 BoostModel m;
                 m.num_dims = 2;
                 m.num_classes = 1;
                 m.class_landmark = {0};
                 m.bias = {0.0, 0.0};
                 write_bytes(dir / "model.bin", as_string(make_container("LMBBOOST", 1, serialize_boost_model(m))));
                 load_trained_model(dir / "model.bin");
               },
               "DIR/model.bin: a model.bin of an older lboost (format version 1), which does not record the context "
               "regions, vocabulary and map it was trained with, so export cannot prove they match; retrain it (or "
               "export it with the lboost that trained it)"});
  // vocab.lbv
  r.push_back({"vocab.lbv", "missing file", [](const fs::path& dir) { Vocabulary::load(dir / "vocab.lbv"); },
               "DIR/vocab.lbv: cannot open file: No such file or directory"});
  r.push_back({"vocab.lbv", "a model file instead", vocab_with(good_model_file),
               "DIR/vocab.lbv: not a LMBVOCAB file (wrong magic)"});
  r.push_back({"vocab.lbv", "format version 2", vocab_with([] { return with_byte(good_vocab_file(), 8, 2); }),
               "DIR/vocab.lbv: format version 2 is not supported (this build reads version 1)"});
  r.push_back({"vocab.lbv", "one payload bit flipped", vocab_with([] {
                 std::string s = good_vocab_file();
                 s[s.size() - 1] ^= 0x01;
                 return s;
               }),
               "DIR/vocab.lbv: CRC mismatch (file is corrupt)"});
  r.push_back({"vocab.lbv", "empty payload behind a valid header",
               vocab_with([] { return as_string(make_container(kVocabularyMagic, kVocabularyVersion, "")); }),
               "DIR/vocab.lbv: truncated vocabulary header (0 payload bytes, expected at least 9)"});
  r.push_back({"vocab.lbv", "3 words (fewer than 4)", vocab_with([] {
                 std::string p = test::test_vocabulary().to_payload();
                 const int32_t three = 3;
                 std::memcpy(p.data() + 1, &three, 4);
                 return as_string(make_container(kVocabularyMagic, kVocabularyVersion, p));
               }),
               "DIR/vocab.lbv: num_words = 3 must be in 4..256"});
  r.push_back({"vocab.lbv", "words cut short", vocab_with([] {
                 std::string p = test::test_vocabulary().to_payload();
                 p.resize(p.size() - 8);
                 return as_string(make_container(kVocabularyMagic, kVocabularyVersion, p));
               }),
               "DIR/vocab.lbv: payload of 33 bytes, expected 41 for 4 words of 8 bytes"});
  // map.h5
  r.push_back(
      {"map.h5", "missing file", [](const fs::path& dir) { read_map_h5(dir / "map.h5"); }, "DIR/map.h5: no such file"});
  r.push_back({"map.h5", "a text file",
               [](const fs::path& dir) {
                 write_bytes(dir / "map.h5", "frames and keypoints, but as text rather than HDF5\n");
                 read_map_h5(dir / "map.h5");
               },
               "DIR/map.h5: not an HDF5 file (expected a landmarkboost-map)"});
  r.push_back({"map.h5", "truncated to half",
               [](const fs::path& dir) {
                 write_map_h5(test::random_map(3), dir / "full.h5");
                 const std::string b = read_bytes(dir / "full.h5");
                 write_bytes(dir / "map.h5", b.substr(0, b.size() / 2));
                 read_map_h5(dir / "map.h5");
               },
               "DIR/map.h5: cannot open as HDF5 (truncated or damaged file): H5Fopen failed"});
  r.push_back({"map.h5", "damaged variable-length string (a fuzzer's input)",
               [](const fs::path& dir) {
                 const char* source = std::getenv("LMB_SOURCE_DIR");
                 if (source == nullptr) throw std::logic_error("LMB_SOURCE_DIR is not set (ctest sets it)");
                 fs::copy_file(fs::path(source) / "test/common/io/data/fuzz_null_vlen_string.h5", dir / "map.h5");
                 read_map_h5(dir / "map.h5");
               },
               "DIR/map.h5: attribute 'format': unreadable (damaged file)"});
  r.push_back(
      {"map.h5", "format_version 3", map_edited([](H5::H5File& f) {
         const int v = 3;
         f.openAttribute("format_version").write(H5::PredType::NATIVE_INT, &v);
       }),
       "DIR/map.h5: attribute 'format_version': version 3 is not supported (this build reads versions 1 and 2)"});
  r.push_back({"map.h5", "a frame's session out of range", map_edited([](H5::H5File& f) {
                 H5::DataSet ds = f.openDataSet("/frames/session");
                 std::vector<int32_t> v(5);
                 ds.read(v.data(), H5::PredType::NATIVE_INT32);
                 v[1] = 3;
                 ds.write(v.data(), H5::PredType::NATIVE_INT32);
               }),
               "DIR/map.h5: frames[1].session: 3 outside 0..2"});
  r.push_back({"map.h5", "a query frame in a map session", map_edited([](H5::H5File& f) {
                 H5::DataSet ds = f.openDataSet("/frames/session");
                 std::vector<int32_t> v(5);
                 ds.read(v.data(), H5::PredType::NATIVE_INT32);
                 v[4] = 0;
                 ds.write(v.data(), H5::PredType::NATIVE_INT32);
               }),
               "DIR/map.h5: frames[4].is_query: 1, but its session 'map' is a map session (is_query must be 1 exactly "
               "for frames outside map sessions)"});
  r.push_back({"map.h5", "dataset /landmarks/quality missing",
               map_edited([](H5::H5File& f) { f.unlink("/landmarks/quality"); }),
               "DIR/map.h5: dataset '/landmarks/quality': missing"});
  r.push_back({"map.h5", "NaN camera translation of a frame",
               map_edited(set_double("/frames/cam_from_world_t", 4, nan)),
               "DIR/map.h5: frames[1].cam_from_world_t: not finite"});
  r.push_back({"map.h5", "infinite camera parameter",
               map_edited(set_double("/cameras/params", 0, std::numeric_limits<double>::infinity())),
               "DIR/map.h5: cameras[0]: camera parameter 0 is not finite"});
  r.push_back({"map.h5", "quaternion of norm 1.5 (not a rotation)", map_edited([](H5::H5File& f) {
                 H5::DataSet ds = f.openDataSet("/frames/cam_from_world_q");
                 std::vector<double> v(20);
                 ds.read(v.data(), H5::PredType::NATIVE_DOUBLE);
                 for (int i = 4; i < 8; ++i) v[i] *= 1.5;
                 ds.write(v.data(), H5::PredType::NATIVE_DOUBLE);
               }),
               "DIR/map.h5: frames[1].cam_from_world_q: not a rotation (norm 1.5)"});
  r.push_back({"map.h5", "NaN landmark position", map_edited(set_double("/landmarks/position", 4, nan)),
               "DIR/map.h5: landmarks[1].position: not finite"});
  r.push_back({"map.h5", "gravity of length 2", map_edited([](H5::H5File& f) {
                 H5::DataSet ds = f.openDataSet("/frames/gravity_in_cam");
                 std::vector<double> v(15);
                 ds.read(v.data(), H5::PredType::NATIVE_DOUBLE);
                 for (int i = 0; i < 3; ++i) v[i] *= 2.0;
                 ds.write(v.data(), H5::PredType::NATIVE_DOUBLE);
               }),
               "DIR/map.h5: frames[0].gravity_in_cam: not a unit vector"});
  r.push_back({"map.h5", "keypoint landmark id past the last landmark", map_edited([](H5::H5File& f) {
                 H5::DataSet ds = f.openDataSet("/keypoints/landmark");
                 std::vector<int64_t> v(40);
                 ds.read(v.data(), H5::PredType::NATIVE_INT64);
                 v[7] = 6;
                 ds.write(v.data(), H5::PredType::NATIVE_INT64);
               }),
               "DIR/map.h5: keypoint_landmark[7]: 6 outside -1..5"});
  // COLMAP text
  r.push_back({"COLMAP text", "folder with neither format",
               [](const fs::path& dir) {
                 fs::create_directories(dir / "sparse");
                 read_colmap_model(dir / "sparse");
               },
               "DIR/sparse: no COLMAP sparse model (expected cameras.bin + images.bin or cameras.txt + images.txt)"});
  r.push_back({"COLMAP text", "fisheye camera model",
               colmap_text_with("cameras.txt", "1 OPENCV_FISHEYE 640 480 500 500 320 240 0 0 0 0\n"),
               "DIR/sparse/cameras.txt line 1: unsupported camera model 'OPENCV_FISHEYE' (supported: SIMPLE_PINHOLE, "
               "PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV)"});
  r.push_back({"COLMAP text", "3 parameters for PINHOLE",
               colmap_text_with("cameras.txt", "1 PINHOLE 640 480 500 500 320\n"),
               "DIR/sparse/cameras.txt line 1: camera model PINHOLE takes 4 parameters, got 3"});
  r.push_back({"COLMAP text", "NaN focal length",
               colmap_text_with("cameras.txt", "1 PINHOLE 640 480 nan 500 320 240\n"),
               "DIR/sparse/cameras.txt line 1: field 'PARAMS[]' is not finite"});
  r.push_back({"COLMAP text", "quaternion of norm 1.06",
               colmap_text_with("images.txt", "1 0.5 0.5 0.5 0.6 0 0 0 1 a.png\n\n"),
               "DIR/sparse/images.txt line 1: quaternion is not a rotation (norm 1.05357, expected 1)"});
  r.push_back({"COLMAP text", "NaN translation", colmap_text_with("images.txt", "1 1 0 0 0 0 nan 0 1 a.png\n\n"),
               "DIR/sparse/images.txt line 1: field 'TY' is not finite"});
  r.push_back({"COLMAP text", "image of a missing camera",
               colmap_text_with("images.txt", "1 1 0 0 0 0 0 0 9 a.png\n\n"),
               "DIR/sparse/images.txt line 1: image refers to camera 9, which cameras.txt lacks"});
  r.push_back({"COLMAP text", "duplicate image name",
               colmap_text_with("images.txt", "1 1 0 0 0 0 0 0 1 a.png\n\n2 1 0 0 0 0 0 0 1 a.png\n\n"),
               "DIR/sparse/images.txt line 3: duplicate image name a.png"});
  r.push_back({"COLMAP text", "image name with '..' (would leave the image folder)",
               colmap_text_with("images.txt", "1 1 0 0 0 0 0 0 1 ../../a.png\n\n"),
               "DIR/sparse/images.txt line 1: image name '../../a.png' leaves the image folder ('..' component)"});
  r.push_back({"COLMAP text", "absolute image name",
               colmap_text_with("images.txt", "1 1 0 0 0 0 0 0 1 /etc/passwd\n\n"),
               "DIR/sparse/images.txt line 1: image name '/etc/passwd' is an absolute path (names are relative to the "
               "image folder)"});
  r.push_back({"COLMAP text", "image id -5", colmap_text_with("images.txt", "-5 1 0 0 0 0 0 0 1 a.png\n\n"),
               "DIR/sparse/images.txt line 1: IMAGE_ID -5 is negative"});
  r.push_back({"COLMAP text", "NUL byte in an image name",
               colmap_text_with("images.txt", std::string("1 1 0 0 0 0 0 0 1 a") + '\0' + "b.png\n\n"),
               "DIR/sparse/images.txt line 1: contains a NUL byte (not a text file?)"});
  r.push_back({"COLMAP text", "track of a missing image", colmap_text_with("points3D.txt", "5 1 2 3 0 0 0 0.5 7 0\n"),
               "DIR/sparse/points3D.txt line 1: track refers to image 7, which the model lacks"});
  // COLMAP binary
  r.push_back({"COLMAP binary", "cameras.bin cut by 3 bytes",
               colmap_binary_with({}, "cameras.bin", [](std::string& b) { b.resize(b.size() - 3); }),
               "DIR/sparse/cameras.bin: camera record 0 (id 1): truncated file: cannot read camera parameter (8 bytes "
               "needed, 5 left) (at byte offset 56 of 61)"});
  r.push_back({"COLMAP binary", "image count 2^60",
               colmap_binary_with({}, "images.bin",
                                  [](std::string& b) {
                                    const uint64_t huge = uint64_t{1} << 60;
                                    std::memcpy(b.data(), &huge, 8);
                                  }),
               "DIR/sparse/images.bin: number of images is 1152921504606846976 but only 208 bytes are left (at least "
               "73 per record) (at byte offset 8 of 216)"});
  r.push_back({"COLMAP binary", "unknown camera model id 42",
               colmap_binary_with({}, "cameras.bin",
                                  [](std::string& b) {
                                    const int32_t id = 42;
                                    std::memcpy(b.data() + 12, &id, 4);
                                  }),
               "DIR/sparse/cameras.bin: camera record 0 (id 1): unknown camera model id 42 (at byte offset 16 of 64)"});
  r.push_back({"COLMAP binary", "quaternion of norm 1.2",
               colmap_binary_with([](ColmapModel& m) { m.images[0].cam_from_world.rotation.coeffs() *= 1.2; }),
               "DIR/sparse/images.bin: image record 0 (id 1): quaternion is not a rotation (norm 1.2, expected 1)"});
  r.push_back({"COLMAP binary", "NaN translation",
               colmap_binary_with([nan](ColmapModel& m) { m.images[1].cam_from_world.translation.z() = nan; }),
               "DIR/sparse/images.bin: image record 1 (id 2): translation component is not finite (at byte offset 172 "
               "of 216)"});
  r.push_back({"COLMAP binary", "track of a 2D point the image lacks",
               colmap_binary_with([](ColmapModel& m) { m.points[0].track[1].point2d_idx = 4; }),
               "DIR/sparse/points3D.bin: point3D record 0 (id 5): track refers to 2D point 4 of image 2, which has 1 "
               "(at byte offset 75 of 75)"});
  r.push_back({"COLMAP binary", "image name with '..' (would leave the image folder)",
               colmap_binary_with([](ColmapModel& m) { m.images[1].name = "../b.png"; }),
               "DIR/sparse/images.bin: image record 1 (id 2): image name '../b.png' leaves the image folder ('..' "
               "component) (at byte offset 185 of 217)"});
  r.push_back(
      {"COLMAP binary", "trailing bytes", colmap_binary_with({}, "points3D.bin", [](std::string& b) { b += "xyz"; }),
       "DIR/sparse/points3D.bin: 3 trailing bytes after the last record (wrong count?) (at byte offset 75 of 78)"});
  // bundle.txt (infer/bundle_index.h)
  r.push_back({"bundle.txt", "format version 5", bundle_with(replaced("lmb-bundle 4", "lmb-bundle 5")),
               "DIR/bundle.txt line 1: format version 5 is not supported (this build reads 1 to 4)"});
  r.push_back({"bundle.txt", "reach not a number", bundle_with(replaced("reach 1", "reach x")),
               "DIR/bundle.txt line 3: reach is not a number: 'x'"});
  r.push_back({"bundle.txt", "map fingerprint not 16 hex digits",
               bundle_with(replaced("map 5eed0f0e5eed0f0e", "map x")),
               "DIR/bundle.txt line 4: map is not 16 hex digits: 'x'"});
  r.push_back({"bundle.txt", "calibration line one value short",
               bundle_with(replaced("areas 1", "calibration 0 0 0 0 0 0 0 0 0.5 10 5\nareas 1")),
               "DIR/bundle.txt line 5: expected 'calibration' and 12 value(s), found 'calibration 0 0 0 0 0 0 0 0 0.5 "
               "10 5'"});
  r.push_back({"bundle.txt", "calibration threshold 1.5",
               bundle_with(replaced("areas 1", "calibration 0 0 0 0 0 0 0 0 1.5 10 5 0.95\nareas 1")),
               "DIR/bundle.txt line 5: calibration: threshold 1.5 is outside [0, 1]"});
  r.push_back({"bundle.txt", "walk calibration max_gap 0",
               bundle_with(replaced("areas 1",
                                    "calibration 0 0 0 0 0 0 0 0 0.5 10 5 0.95\nwalk_calibration 0 0 0 0 1 "
                                    "0.5 0.01 1 0 1 0.01 0.5 0.01 1 10 5 0.95\nareas 1")),
               "DIR/bundle.txt line 6: walk calibration: max_gap 0 is outside 1..1000"});
  r.push_back({"bundle.txt", "an area file outside the bundle folder",
               bundle_with(replaced("file area-0.lbm", "file ../area-0.lbm")),
               "DIR/bundle.txt line 6: file '../area-0.lbm' must be a file name in the bundle's folder (no folder, no "
               "'..', printable UTF-8)"});
  r.push_back({"bundle.txt", "two areas name one file",
               bundle_with(replaced("file area-1.lbm", "file area-0.lbm"), {}, {good_model_data(), good_model_data()}),
               "DIR/bundle.txt line 7: file 'area-0.lbm' is another area's model too"});
  r.push_back({"bundle.txt", "an area's class count not its model's",
               bundle_with(replaced("landmarks 3 first_landmark", "landmarks 2 first_landmark"),
                           [](AreaBundle& b) { b.model(0); }),
               "DIR: area 0 (area-0.lbm): 3 classes, the bundle index says 2 (a model of another area or map)"});
  r.push_back({"bundle.txt", "an area's model of another map (classes differ)",
               bundle_with(
                   [](std::string& text) {
                     const size_t at = text.rfind(" classes ") + 9;  // the area line, not the comment
                     text[at] = text[at] == '1' ? '2' : '1';
                   },
                   [](AreaBundle& b) { b.model(0); }),
               "DIR: area 0 (area-0.lbm): its classes (landmark ids and positions) differ from the ones the bundle "
               "index records (a model of another area or map)"});
  r.push_back({"bundle.txt", "an area's model damaged (one byte)",
               bundle_with({},
                           [](AreaBundle& b) {
                             const fs::path path = b.index_path().parent_path() / "area-0.lbm";
                             std::string image = read_bytes(path);
                             image[image.size() / 2] ^= 0x10;
                             write_bytes(path, image);
                             b.model(0);
                           }),
               "DIR: area 0 (area-0.lbm): CRC-32 mismatch with the bundle index (a different or damaged file)"});
  r.push_back({"bundle.txt", "areas of two descriptor lengths",
               bundle_with({},
                           [](AreaBundle& b) {
                             b.model(0);
                             b.model(1);
                           },
                           {good_model_data(),
                            [] {
                              ModelData d = good_model_data();
                              d.descriptor_bytes = 2 * test::kCodeDescriptorBytes;
                              std::vector<uint8_t> words(4 * static_cast<size_t>(d.descriptor_bytes), 0x5a);
                              for (size_t i = 0; i < words.size(); ++i) words[i] = static_cast<uint8_t>(i * 37);
                              d.vocabulary = Vocabulary(d.descriptor_bytes, words);
                              return d;
                            }()}),
               "DIR: area 1 (area-1.lbm): 16-byte descriptors, the bundle's areas loaded before have 8"});
  // gravity.txt
  r.push_back({"gravity.txt", "3 fields", gravity_with("im1.png 0 1\n"),
               "DIR/gravity.txt line 1: expected 4 fields (IMAGE_NAME GX GY GZ), got 3"});
  r.push_back({"gravity.txt", "NaN component", gravity_with("im1.png 0 nan 1\nim2.png 0 1 0\n"),
               "DIR/gravity.txt line 1: GY is not finite"});
  r.push_back({"gravity.txt", "zero vector", gravity_with("im1.png 0 0 0\nim2.png 0 1 0\n"),
               "DIR/gravity.txt line 1: gravity of image im1.png is the zero vector"});
  r.push_back({"gravity.txt", "image not in the model", gravity_with("im1.png 0 1 0\nim2.png 0 1 0\nim3.png 0 1 0\n"),
               "DIR/gravity.txt: image name im3.png is not in the sparse model"});
  r.push_back({"gravity.txt", "image of the model missing", gravity_with("im1.png 0 1 0\n"),
               "DIR/gravity.txt: no gravity for image im2.png (image id 2)"});
  // training configs
  r.push_back({"train config (TOML)", "syntax error", config_with("[boost\nnum_rounds = 3\n"),
               "DIR/train.toml: Error while parsing table header: expected ']', saw '\\n' at line 1"});
  r.push_back({"train config (TOML)", "unknown key", config_with("[boost]\nnum_round = 3\n"),
               "DIR/train.toml: unknown key boost.num_round"});
  r.push_back({"train config (TOML)", "string for an integer", config_with("[boost]\nnum_rounds = \"many\"\n"),
               "DIR/train.toml: boost.num_rounds: expected an integer"});
  r.push_back({"train config (TOML)", "1e37 for an integer", config_with("[boost]\nnum_rounds = 1e37\n"),
               "DIR/train.toml: boost.num_rounds: expected an integer"});
  r.push_back({"train config (TOML)", "integer out of range", config_with("[boost]\nnum_rounds = 99999999999\n"),
               "DIR/train.toml: boost.num_rounds: 99999999999 is out of range"});
  r.push_back({"train config (TOML)", "num_rounds = 0", config_with("[boost]\nnum_rounds = 0\n"),
               "DIR/train.toml: boost options: num_rounds must be >= 1, got 0"});
  r.push_back({"train config (TOML)", "nan for a real", config_with("[boost]\nexclusion_radius = nan\n"),
               "DIR/train.toml: boost options: exclusion_radius must be finite and >= 0, got nan"});
  r.push_back({"train config (TOML)", "inf region area", config_with("[regions]\nmax_area = inf\n"),
               "DIR/train.toml: context regions: max_area = inf must be finite and >= min_area (1)"});
  r.push_back({"train config (TOML)", "negative seed", config_with("[regions]\nseed = -1\n"),
               "DIR/train.toml: regions.seed: -1 is out of range"});
  // sessions.txt (common/io/session_file.h)
  r.push_back({"sessions.txt", "duplicate name", sessions_with("map map\nquery query\nmap outside\n"),
               "DIR/sessions.txt line 3: duplicate session name map (first on line 1)"});
  r.push_back({"sessions.txt", "NUL byte in a name", sessions_with(std::string("map map\nqu\0ery query\n", 21)),
               "DIR/sessions.txt line 2: session name 'qu\\0ery' (expected letters, digits, '-', '_' or '.': the "
               "image folder of the session)"});
  // areas.txt (train/areas/area_file.h)
  r.push_back({"areas.txt", "areas 1000000 in a file of one area",
               areas_with([](std::string& text) { text.replace(text.find("\nareas 1\n"), 9, "\nareas 1000000\n"); }),
               "DIR/areas.txt line 10: areas 1000000, but the file has only 2 line(s) left (each area needs an area "
               "and a members line)"});
  r.push_back({"areas.txt", "map_landmarks 2147483647 (the map has 6)", areas_with([](std::string& text) {
                 text.replace(text.find("map_landmarks 6"), 15, "map_landmarks 2147483647");
               }),
               "DIR/areas.txt: map_landmarks 2147483647, but its map has 6 landmarks (an edited or damaged file); run "
               "lboost areas on this map"});
  return r;
}

class InputValidationTest : public ::testing::Test {
 protected:
  void SetUp() override {
    H5::Exception::dontPrint();
    dir_ = fs::temp_directory_path() / ("lmb_input_validation_" + std::to_string(::getpid()));
  }
  void TearDown() override { fs::remove_all(dir_); }

  // The message of the row's error with the scratch folder replaced by DIR, or "(accepted)".
  std::string message_of(const Row& row) {
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    try {
      row.load(dir_);
    } catch (const Error& e) {
      std::string m = e.what();
      const std::string d = dir_.string();
      for (size_t at = m.find(d); at != std::string::npos; at = m.find(d, at)) m.replace(at, d.size(), "DIR");
      return m;
    }
    return "(accepted)";
  }
  fs::path dir_;
};

TEST_F(InputValidationTest, EveryBadInputFailsWithTheDocumentedLine) {
  for (const Row& row : rows()) {
    const std::string got = message_of(row);
    EXPECT_EQ(got, row.message) << row.file << ", " << row.defect;
    EXPECT_EQ(got.find('\n'), std::string::npos) << row.file << ", " << row.defect;
  }
}

TEST_F(InputValidationTest, TheDocumentListsEveryRow) {
  const char* source = std::getenv("LMB_SOURCE_DIR");
  ASSERT_NE(source, nullptr) << "LMB_SOURCE_DIR is not set (ctest sets it)";
  const std::string doc = read_bytes(fs::path(source) / "docs" / "input_validation.md");
  ASSERT_FALSE(doc.empty()) << "docs/input_validation.md is missing";
  for (const Row& row : rows()) {
    const std::string line = "| " + row.file + " | " + row.defect + " | `" + row.message + "` |";
    EXPECT_NE(doc.find(line), std::string::npos) << "docs/input_validation.md lacks the row\n" << line;
  }
}

}  // namespace
}  // namespace lmb
