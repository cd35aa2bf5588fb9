// model.lbm: round trip, and rejection of damaged files with bounded memory.
#include "infer/model.h"
#include "infer/detail/model_format.h"
#include "infer/detail/scoring_index.h"

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <new>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/file_container.h"
#include "common/random.h"
#include "test/infer/test_models.h"

// GCC flags free() on memory from the replaced operator new below; they are a matching pair.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

// Every allocation of this test binary goes through here, so that tests can assert that parsing
// a corrupt file never asks for a large block (cereal would trust a corrupt size field).
namespace {
std::atomic<size_t> largest_allocation{0};
}  // namespace

namespace {
void* counted_malloc(size_t size) {
  size_t seen = largest_allocation.load(std::memory_order_relaxed);
  while (size > seen && !largest_allocation.compare_exchange_weak(seen, size)) {
  }
  return std::malloc(size == 0 ? 1 : size);
}
}  // namespace

void* operator new(size_t size) {
  if (void* p = counted_malloc(size)) return p;
  throw std::bad_alloc();
}
// The nothrow form too (std::stable_sort's temporary buffer): under AddressSanitizer an
// unreplaced one would come from its allocator and reach free() below.
void* operator new(size_t size, const std::nothrow_t&) noexcept { return counted_malloc(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t) noexcept { std::free(p); }

namespace lmb {
namespace {

using test::make_code_model_data;

std::vector<Eigen::Vector3d> some_positions(int n) {
  std::vector<Eigen::Vector3d> p;
  for (int i = 0; i < n; ++i) p.emplace_back(i, 2.0 * i, -0.5 * i);
  return p;
}

std::vector<uint8_t> small_model_file() { return Model(make_code_model_data(some_positions(5))).to_bytes(); }

std::string expect_rejected(const std::vector<uint8_t>& bytes) {
  try {
    Model::from_bytes(bytes.data(), bytes.size(), "test.lbm");
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "a damaged model was accepted";
  return "";
}

TEST(ModelTest, RoundTripKeepsEverything) {
  const ModelData d = make_code_model_data(some_positions(7));
  const Model m(d);
  const std::vector<uint8_t> bytes = m.to_bytes();
  const auto back = Model::from_bytes(bytes.data(), bytes.size());
  const ModelData& e = back->data();
  EXPECT_EQ(e.detector, d.detector);
  EXPECT_EQ(e.descriptor_bytes, d.descriptor_bytes);
  EXPECT_TRUE(e.regions == d.regions);
  EXPECT_TRUE(e.vocabulary == d.vocabulary);
  EXPECT_EQ(e.num_classes, d.num_classes);
  EXPECT_EQ(e.class_landmark, d.class_landmark);
  EXPECT_EQ(e.class_position, d.class_position);
  EXPECT_EQ(e.bias, d.bias);
  ASSERT_EQ(e.stumps.size(), d.stumps.size());
  for (size_t i = 0; i < d.stumps.size(); ++i) {
    EXPECT_EQ(e.stumps[i].dim, d.stumps[i].dim);
    EXPECT_EQ(e.stumps[i].theta, d.stumps[i].theta);
    EXPECT_EQ(e.stumps[i].a, d.stumps[i].a);
    EXPECT_EQ(e.stumps[i].b, d.stumps[i].b);
    EXPECT_EQ(e.stumps[i].classes, d.stumps[i].classes);
  }
  EXPECT_EQ(e.inverted_file, d.inverted_file);
  // Serialization is deterministic: the same bytes again.
  EXPECT_EQ(back->to_bytes(), bytes);
}

// A code model with a descriptor-distance fusion: class c's exemplars are 1 + c % 3 rows.
ModelData code_model_with_fusion(int n) {
  ModelData d = make_code_model_data(some_positions(n));
  Rng rng(8);
  d.fusion.exemplar_begin = {0};
  for (int32_t c = 0; c < d.num_classes; ++c) {
    for (int r = 0; r <= c % 3; ++r) {
      for (int b = 0; b < d.descriptor_bytes; ++b) d.fusion.exemplars.push_back(static_cast<uint8_t>(rng.below(256)));
    }
    d.fusion.exemplar_begin.push_back(d.fusion.exemplar_begin.back() + 1 + c % 3);
  }
  for (int dist = 0; dist <= 8 * d.descriptor_bytes; ++dist) d.fusion.distance_score.push_back(2.0 - 0.07 * dist);
  return d;
}

TEST(ModelTest, FusionRoundTripAndFileVersions) {
  const ModelData d = code_model_with_fusion(6);
  const Model m(d);
  EXPECT_TRUE(m.has_fusion());
  EXPECT_EQ(m.scoring().fusion_max(), 2.0);
  const std::vector<uint8_t> bytes = m.to_bytes();
  EXPECT_EQ(bytes[8], kModelVersionWithFusion);  // version 2: the fusion follows the inverted file
  const auto back = Model::from_bytes(bytes.data(), bytes.size());
  EXPECT_EQ(back->data().fusion.exemplar_begin, d.fusion.exemplar_begin);
  EXPECT_EQ(back->data().fusion.exemplars, d.fusion.exemplars);
  EXPECT_EQ(back->data().fusion.distance_score, d.fusion.distance_score);
  EXPECT_EQ(back->to_bytes(), bytes);
  // Without a fusion the file is version 1 and its payload the same bytes as with the fusion
  // left out: a model of the unchanged method is written as before.
  ModelData plain = d;
  plain.fusion = DescriptorFusion{};
  const std::vector<uint8_t> plain_bytes = Model(plain).to_bytes();
  EXPECT_EQ(plain_bytes[8], kModelVersionWithoutFusion);
  EXPECT_FALSE(Model::from_bytes(plain_bytes.data(), plain_bytes.size())->has_fusion());
  const std::string with = serialize_model_data(d), without = serialize_model_data(plain);
  ASSERT_LT(without.size(), with.size());
  EXPECT_EQ(with.substr(0, without.size()), without);
  // A version-1 header on a fusion payload (or the reverse) is rejected by the parser.
  EXPECT_THROW(parse_model_data(with, "t", kModelVersionWithoutFusion), Error);
  EXPECT_THROW(parse_model_data(without, "t", kModelVersionWithFusion), Error);
  // Truncated anywhere in the fusion section: an error, never a crash.
  for (size_t size = without.size(); size < with.size(); ++size) {
    EXPECT_THROW(parse_model_data(with.substr(0, size), "t", kModelVersionWithFusion), Error) << "cut at " << size;
  }
  // The term: the table at the nearest exemplar's distance.
  const uint8_t* e = d.fusion.exemplars.data() + d.fusion.exemplar_begin[4] * d.descriptor_bytes;
  EXPECT_EQ(detail::fusion_term(m, 4, e), 2.0);
  EXPECT_EQ(detail::fusion_term(Model(plain), 4, e), 0.0);
}

PoseCalibration some_calibration() {
  PoseCalibration c;
  for (int k = 0; k < PoseEvidence::kNumFeatures; ++k) c.weights[k] = 0.1 * (k + 1) - 0.37 + 1e-13 * k;
  c.bias = -1.2345678901234567;
  c.threshold = 0.8123456789;
  c.num_samples = 321;
  c.num_positive = 123;
  c.target_precision = 0.95;
  return c;
}

// Version 3: the calibration round-trips bit for bit, with or without a fusion; a model without
// one is written as before (version 1 or 2) and loads uncalibrated.
TEST(ModelTest, CalibrationRoundTripBitForBitAndOlderVersionsLoadUncalibrated) {
  for (bool fusion : {false, true}) {
    ModelData d = fusion ? code_model_with_fusion(6) : make_code_model_data(some_positions(6));
    const std::vector<uint8_t> old_bytes = Model(d).to_bytes();
    EXPECT_EQ(old_bytes[8], fusion ? kModelVersionWithFusion : kModelVersionWithoutFusion);
    const auto old = Model::from_bytes(old_bytes.data(), old_bytes.size());
    EXPECT_FALSE(old->calibrated());
    d.calibration = some_calibration();
    const Model m(d);
    ASSERT_TRUE(m.calibrated());
    const std::vector<uint8_t> bytes = m.to_bytes();
    EXPECT_EQ(bytes[8], kModelVersion);
    const auto back = Model::from_bytes(bytes.data(), bytes.size());
    ASSERT_TRUE(back->calibrated());
    const PoseCalibration& a = d.calibration.value();
    const PoseCalibration& b = back->calibration();
    EXPECT_EQ(std::memcmp(a.weights.data(), b.weights.data(), sizeof(a.weights)), 0);
    EXPECT_EQ(std::memcmp(&a.bias, &b.bias, sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(&a.threshold, &b.threshold, sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(&a.target_precision, &b.target_precision, sizeof(double)), 0);
    EXPECT_EQ(b.num_samples, a.num_samples);
    EXPECT_EQ(b.num_positive, a.num_positive);
    EXPECT_EQ(back->has_fusion(), fusion);
    EXPECT_EQ(back->data().fusion.distance_score, d.fusion.distance_score);
    EXPECT_EQ(back->to_bytes(), bytes);
    // Truncated anywhere after the version-1 part: an error, never a crash.
    const std::string payload = serialize_model_data(d);
    for (size_t size = payload.size() - 90; size < payload.size(); ++size) {
      EXPECT_THROW(parse_model_data(payload.substr(0, size), "t", kModelVersion), Error) << "cut at " << size;
    }
  }
}

// The walk calibration of `d` after a round trip through its bytes, which are written as
// `version` and come back bit for bit.
WalkCalibration walk_round_trip(const ModelData& d, uint32_t version) {
  const std::vector<uint8_t> bytes = Model(d).to_bytes();
  EXPECT_EQ(bytes[8], version);
  const auto back = Model::from_bytes(bytes.data(), bytes.size());
  EXPECT_EQ(back->to_bytes(), bytes);
  EXPECT_TRUE(back->walk_calibration().has_value());
  return back->walk_calibration().value_or(WalkCalibration{});
}

// Every cut of `payload` in its last `tail` bytes fails to parse as `version`.
void expect_cuts_rejected(const std::string& payload, size_t tail, uint32_t version) {
  for (size_t size = payload.size() - tail; size < payload.size(); ++size) {
    EXPECT_THROW(parse_model_data(payload.substr(0, size), "t", version), Error) << "cut at " << size;
  }
}

// Version 4: the walk calibration round-trips bit for bit beside the pose calibration; without it
// the model is written as version 3; a walk calibration without a pose calibration, a corrupt
// field or a cut anywhere in it is an error.
TEST(ModelTest, WalkCalibrationRoundTripsAsVersion4) {
  ModelData d = make_code_model_data(some_positions(6));
  d.calibration = some_calibration();
  EXPECT_EQ(Model(d).to_bytes()[8], kModelVersion);
  WalkCalibration w;
  w.weights = {0.8, -1.5, -2.25, -0.5};
  w.bias = 1.25;
  w.threshold = 0.6;
  w.translation_scale_m = 0.31;
  w.rotation_scale_deg = 7.5;
  w.max_gap = 4;
  w.num_samples = 40;
  w.num_positive = 22;
  w.target_precision = 0.95;
  d.walk_calibration = w;
  const WalkCalibration b = walk_round_trip(d, kModelVersionWithWalk);
  EXPECT_EQ(std::memcmp(w.weights.data(), b.weights.data(), sizeof(w.weights)), 0);
  EXPECT_EQ(b.bias, w.bias);
  EXPECT_EQ(b.threshold, w.threshold);
  EXPECT_EQ(b.translation_scale_m, w.translation_scale_m);
  EXPECT_EQ(b.rotation_scale_deg, w.rotation_scale_deg);
  EXPECT_EQ(b.max_gap, w.max_gap);
  EXPECT_EQ(b.num_samples, w.num_samples);
  EXPECT_EQ(b.num_positive, w.num_positive);
  const std::string payload = serialize_model_data(d);
  expect_cuts_rejected(payload, 90, kModelVersionWithWalk);
  // Read as version 3, the walk calibration is bytes after the model.
  EXPECT_THROW(parse_model_data(payload, "t", kModelVersion), Error);
  ModelData no_pose = d;
  no_pose.calibration.reset();
  EXPECT_THROW(Model{no_pose}, Error);
  ModelData bad = d;
  bad.walk_calibration->rotation_scale_deg = -1.0;
  try {
    Model{bad};
    ADD_FAILURE() << "a negative rotation scale was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("rotation_scale_deg"), std::string::npos) << e.what();
  }
}

// Version 5: a walk calibration with agreement (or without a walk rule) round-trips bit for bit;
// version 4 files read as a walk rule without agreement; a cut or a flag other than 0 or 1 is an
// error.
TEST(ModelTest, WalkAgreementRoundTripsAsVersion5) {
  ModelData d = make_code_model_data(some_positions(6));
  d.calibration = some_calibration();
  WalkCalibration w;
  w.translation_scale_m = 0.31;
  w.rotation_scale_deg = 7.5;
  w.adds = false;
  w.threshold = 1.0;
  w.agreement_noise_m = 0.076;
  w.agreement_noise_deg = 1.96;
  w.agreement_step_m = 0.015;
  w.agreement_step_deg = 0.81;
  d.walk_calibration = w;
  const WalkCalibration b = walk_round_trip(d, kModelVersionWithAgreement);
  EXPECT_FALSE(b.adds);
  EXPECT_EQ(b.agreement_noise_m, w.agreement_noise_m);
  EXPECT_EQ(b.agreement_noise_deg, w.agreement_noise_deg);
  EXPECT_EQ(b.agreement_step_m, w.agreement_step_m);
  EXPECT_EQ(b.agreement_step_deg, w.agreement_step_deg);
  const std::string payload = serialize_model_data(d);
  expect_cuts_rejected(payload, 40, kModelVersionWithAgreement);
  // The adds flag is the byte after the version 4 fields: 2 is refused.
  std::string flag = payload;
  flag[payload.size() - 33] = 2;
  EXPECT_THROW(parse_model_data(flag, "t", kModelVersionWithAgreement), Error);
  // Read as version 4, the agreement is bytes after the model.
  EXPECT_THROW(parse_model_data(payload, "t", kModelVersionWithWalk), Error);
  // A version 4 payload reads as a walk rule that adds poses, without agreement.
  d.walk_calibration->adds = true;
  d.walk_calibration->agreement_noise_m = 0.0;
  EXPECT_EQ(model_file_version(d), kModelVersionWithWalk);
  const ModelData v4 = parse_model_data(serialize_model_data(d), "t", kModelVersionWithWalk);
  EXPECT_TRUE(v4.walk_calibration->adds);
  EXPECT_FALSE(v4.walk_calibration->has_agreement());
  ModelData bad = d;
  bad.walk_calibration->agreement_step_deg = std::nan("");
  EXPECT_THROW(Model{bad}, Error);
}

// A corrupt calibration field fails with one line naming the file and the field.
TEST(ModelTest, CorruptCalibrationFailsNamingTheField) {
  ModelData d = make_code_model_data(some_positions(5));
  d.calibration = some_calibration();
  const std::string payload = serialize_model_data(d);
  // The calibration is the payload's last 4 + 7 * 8 + 8 + 8 + 8 + 8 + 8 bytes (portable binary:
  // little endian).
  const size_t at = payload.size() - (4 + 7 * 8 + 5 * 8);
  const auto rejected = [&](const std::string& bytes) {
    try {
      parse_model_data(bytes, "model.lbm", kModelVersion);
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
      EXPECT_EQ(what.rfind("model.lbm", 0), 0u) << what;
      return what;
    }
    ADD_FAILURE() << "a corrupt calibration was accepted";
    return std::string();
  };
  const auto with_double = [&](size_t offset, double v) {
    std::string bytes = payload;
    std::memcpy(&bytes[offset], &v, sizeof(double));
    return bytes;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(rejected(with_double(at + 4 + 3 * 8, nan)).find("pose calibration: weight 3 (inlier_rank) is not finite"),
            std::string::npos);
  EXPECT_NE(rejected(with_double(at + 4 + 7 * 8, std::numeric_limits<double>::infinity())).find("bias"),
            std::string::npos);
  EXPECT_NE(rejected(with_double(at + 4 + 8 * 8, 1.5)).find("pose calibration: threshold 1.5 is outside [0, 1]"),
            std::string::npos);
  EXPECT_NE(rejected(with_double(at + 4 + 8 * 8, nan)).find("threshold"), std::string::npos);
  EXPECT_NE(rejected(with_double(at + 4 + 11 * 8, -0.5)).find("target_precision"), std::string::npos);
  std::string bytes = payload;
  bytes[at] = 9;  // 9 features
  EXPECT_NE(rejected(bytes).find("pose calibration: 9 features, expected 7"), std::string::npos);
  bytes = payload;
  bytes[at + 4 + 9 * 8 + 7] = static_cast<char>(0x80);  // num_samples negative
  EXPECT_NE(rejected(bytes).find("counts"), std::string::npos);
  // The same through the file loader names the path.
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("lmb_corrupt_calibration_" + std::to_string(::getpid()) + ".lbm");
  const std::vector<uint8_t> file = make_container(kModelMagic, kModelVersion, with_double(at + 4 + 8 * 8, 1.5));
  {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(file.data()), static_cast<std::streamsize>(file.size()));
  }
  try {
    Model::load(path);
    ADD_FAILURE() << "loaded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path.string() + ": pose calibration: threshold"), std::string::npos)
        << e.what();
  }
  std::filesystem::remove(path);
}

TEST(ModelTest, CheckRejectsInconsistentFusion) {
  const ModelData d = code_model_with_fusion(4);
  {
    ModelData x = d;
    x.fusion.exemplar_begin.pop_back();
    EXPECT_THROW(Model{x}, Error);
  }
  {
    ModelData x = d;
    x.fusion.exemplar_begin[2] = x.fusion.exemplar_begin[1];  // class 1 without an exemplar
    EXPECT_THROW(Model{x}, Error);
  }
  {
    ModelData x = d;
    x.fusion.exemplars.pop_back();
    EXPECT_THROW(Model{x}, Error);
  }
  {
    ModelData x = d;
    x.fusion.distance_score.pop_back();
    EXPECT_THROW(Model{x}, Error);
  }
  {
    ModelData x = d;
    x.fusion.distance_score[3] = std::numeric_limits<double>::infinity();
    EXPECT_THROW(Model{x}, Error);
  }
}

TEST(ModelTest, SaveAndLoadFile) {
  // Per process: the generic-SIMD variant of this test runs beside it.
  const auto dir = std::filesystem::temp_directory_path() / ("lmb_model_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const Model m(make_code_model_data(some_positions(4)));
  m.save(dir / "m.lbm");
  const auto back = Model::load(dir / "m.lbm");
  EXPECT_EQ(back->to_bytes(), m.to_bytes());
  EXPECT_THROW(Model::load(dir / "missing.lbm"), Error);
  std::filesystem::remove_all(dir);
}

TEST(ModelTest, IndicesMatchTheStumps) {
  const Model m(make_code_model_data(some_positions(6)));
  const ModelData& d = m.data();
  // Used dims: sorted, unique, and exactly the stumps' dims.
  std::vector<int32_t> dims;
  for (const SharedStump& s : d.stumps) dims.push_back(s.dim);
  std::sort(dims.begin(), dims.end());
  dims.erase(std::unique(dims.begin(), dims.end()), dims.end());
  EXPECT_EQ(m.scoring().used_dims(), dims);
  // Per-class lists hold each class's stumps in training order.
  for (int32_t c = 0; c <= d.num_classes; ++c) {
    std::vector<int32_t> expected;
    for (const SharedStump& s : d.stumps) {
      if (std::binary_search(s.classes.begin(), s.classes.end(), c)) expected.push_back(s.dim);
    }
    std::vector<int32_t> got;
    for (int64_t e = m.scoring().class_stump_begin()[c]; e < m.scoring().class_stump_begin()[c + 1]; ++e) {
      got.push_back(m.scoring().used_dims()[m.scoring().class_stumps()[e].used]);
    }
    EXPECT_EQ(got, expected) << "class " << c;
  }
}

TEST(ModelTest, IdCodingRoundTripAndRejectsCorruptLists) {
  const std::vector<int32_t> ids = {0, 1, 2, 127, 128, 300, 16383, 16384, 2000000};
  const std::string bytes = detail::encode_ascending_ids(ids);
  EXPECT_EQ(detail::decode_ascending_ids(bytes, static_cast<uint32_t>(ids.size()), 2000000, "t"), ids);
  EXPECT_THROW(detail::decode_ascending_ids(bytes, static_cast<uint32_t>(ids.size()), 1999999, "t"), Error);
  EXPECT_THROW(detail::decode_ascending_ids(bytes, static_cast<uint32_t>(ids.size()) - 1, 2000000, "t"), Error);
  EXPECT_THROW(detail::decode_ascending_ids(bytes, 1000000, 2000000, "t"), Error);
  EXPECT_THROW(
      detail::decode_ascending_ids(bytes.substr(0, bytes.size() - 1), static_cast<uint32_t>(ids.size()), 2000000, "t"),
      Error);
  // A zero gap (repeated id) is not ascending.
  EXPECT_THROW(detail::decode_ascending_ids(std::string("\x05\x00", 2), 2, 100, "t"), Error);
}

TEST(ModelTest, RejectsWrongMagicVersionAndCrc) {
  const std::vector<uint8_t> good = small_model_file();
  std::vector<uint8_t> bad = good;
  bad[0] = 'X';
  EXPECT_NE(expect_rejected(bad).find("magic"), std::string::npos);
  bad = good;
  bad[8] = 6;  // version 6
  EXPECT_NE(expect_rejected(bad).find("version"), std::string::npos);
  bad = good;
  bad[kContainerHeaderBytes + 10] ^= 0x40;
  EXPECT_NE(expect_rejected(bad).find("CRC"), std::string::npos);
  // A vocabulary file is not a model.
  const std::vector<uint8_t> vocab =
      make_container(kVocabularyMagic, kVocabularyVersion, test::test_vocabulary().to_payload());
  EXPECT_NE(expect_rejected(vocab).find("magic"), std::string::npos);
}

TEST(ModelTest, RejectsTruncationAtEveryOffset) {
  const std::vector<uint8_t> good = small_model_file();
  for (size_t size = 0; size < good.size(); ++size) {
    const std::vector<uint8_t> cut(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(size));
    expect_rejected(cut);
  }
  // Truncation of the payload behind a valid header (length and CRC fixed up): the parser itself
  // must notice, at every offset.
  const std::string payload = serialize_model_data(make_code_model_data(some_positions(5)));
  largest_allocation = 0;
  for (size_t size = 0; size < payload.size(); ++size) {
    const std::vector<uint8_t> rewrapped =
        make_container(kModelMagic, kModelVersionWithoutFusion, payload.substr(0, size));
    const std::string message = expect_rejected(rewrapped);
    EXPECT_FALSE(message.empty()) << "payload cut at " << size;
  }
  EXPECT_LT(largest_allocation.load(), size_t{1} << 20);
}

TEST(ModelTest, RejectsLargeCountsBeforeAllocating) {
  // Overwrite each 8-byte window of the payload with huge values (valid CRC): every count the
  // parser meets is then larger than the bytes left. Parsing must fail with lmb::Error and never
  // allocate more than a small multiple of the file size.
  const std::string payload = serialize_model_data(make_code_model_data(some_positions(5)));
  int rejected = 0;
  for (uint64_t value : {0xFFFFFFFFFFFFFFFFull, 0x00000000FFFFFFFFull, 0x0000000100000000ull}) {
    for (size_t offset = 0; offset + 8 <= payload.size(); ++offset) {
      std::string bad = payload;
      std::memcpy(bad.data() + offset, &value, 8);
      largest_allocation = 0;
      try {
        parse_model_data(bad, "corrupt.lbm", kModelVersionWithoutFusion);
      } catch (const Error&) {
        ++rejected;
      }
      EXPECT_LT(largest_allocation.load(), size_t{1} << 20) << "offset " << offset;
    }
  }
  EXPECT_GT(rejected, 0);
  // The classic case: the first count (the detector name's size) says 2^60 bytes.
  std::string bad = payload;
  const uint64_t huge = uint64_t{1} << 60;
  std::memcpy(bad.data() + 1, &huge, 8);  // after the archive's endianness byte
  try {
    parse_model_data(bad, "corrupt.lbm");
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("exceeds"), std::string::npos) << e.what();
  }
}

TEST(ModelTest, CheckRejectsInconsistentData) {
  ModelData d = make_code_model_data(some_positions(3));
  {
    ModelData x = d;
    x.bias.pop_back();
    EXPECT_THROW(Model{x}, Error);
  }
  {
    ModelData x = d;
    x.stumps[0].classes = {2, 1};
    EXPECT_THROW(Model{x}, Error);
  }
  {
    ModelData x = d;
    x.stumps[0].classes = {4};  // > C (background is 3)
    EXPECT_THROW(Model{x}, Error);
  }
  {
    ModelData x = d;
    x.inverted_file[0] = {3};  // the background is never a candidate
    EXPECT_THROW(Model{x}, Error);
  }
  {
    ModelData x = d;
    x.stumps[0].dim = detail::layout_of(x).num_dims();
    EXPECT_THROW(Model{x}, Error);
  }
  {
    ModelData x = d;
    x.class_position[1].x() = std::nan("");
    EXPECT_THROW(Model{x}, Error);
  }
  {
    ModelData x = d;
    x.descriptor_bytes = 16;  // the vocabulary's words have 8
    EXPECT_THROW(Model{x}, Error);
  }
}

}  // namespace
}  // namespace lmb
