#include "train/boost/boost_model.h"

#include <cmath>
#include <sstream>

#include <cereal/archives/portable_binary.hpp>
#include <cereal/types/vector.hpp>

#include "common/bounded_reader.h"
#include "common/error.h"
#include "common/file_container.h"
#include "common/file_io.h"

namespace lmb {

namespace {
constexpr char kMagic[] = "LMBBOOST";
constexpr uint32_t kVersion = 2;  // 1: no feature space (refused)
}  // namespace

void BoostModel::scores(const uint8_t* v, double* out) const {
  for (int32_t c = 0; c <= num_classes; ++c) out[c] = bias[c];
  for (const SharedStump& s : stumps) {
    if (s.classes.empty()) continue;
    const double h = (v[s.dim] > s.theta ? s.a : 0.0) + s.b;
    for (int32_t c : s.classes) out[c] += h;
  }
}

double BoostModel::score(const uint8_t* v, int32_t c) const {
  double total = bias[c];
  for (const SharedStump& s : stumps) {
    if (std::binary_search(s.classes.begin(), s.classes.end(), c)) {
      total += (v[s.dim] > s.theta ? s.a : 0.0) + s.b;
    }
  }
  return total;
}

int32_t BoostModel::classify(const uint8_t* v) const {
  std::vector<double> s(static_cast<size_t>(num_classes) + 1);
  scores(v, s.data());
  int32_t best = 0;
  for (int32_t c = 1; c <= num_classes; ++c) {
    if (s[c] > s[best]) best = c;
  }
  return best;
}

void BoostModel::check() const {
  LMB_CHECK(num_classes >= 1 && num_dims >= 1,
            "boost model: empty (" << num_classes << " classes, " << num_dims << " dims)");
  LMB_CHECK(static_cast<int32_t>(class_landmark.size()) == num_classes,
            "boost model: class_landmark has " << class_landmark.size() << " entries, expected " << num_classes);
  LMB_CHECK(static_cast<int32_t>(bias.size()) == num_classes + 1,
            "boost model: bias has " << bias.size() << " entries, expected " << num_classes + 1);
  for (double x : bias) LMB_CHECK(std::isfinite(x), "boost model: non-finite class bias");
  for (size_t m = 0; m < stumps.size(); ++m) {
    const SharedStump& s = stumps[m];
    LMB_CHECK(std::isfinite(s.a) && std::isfinite(s.b), "boost model: stump " << m << " has non-finite a/b");
    LMB_CHECK(s.theta < 255, "boost model: stump " << m << " has threshold 255");
    if (s.classes.empty()) continue;
    LMB_CHECK(s.dim >= 0 && s.dim < num_dims,
              "boost model: stump " << m << " dim " << s.dim << " outside [0, " << num_dims << ")");
    for (size_t i = 0; i < s.classes.size(); ++i) {
      LMB_CHECK(s.classes[i] >= 0 && s.classes[i] <= num_classes,
                "boost model: stump " << m << " shares class " << s.classes[i] << " out of range");
      LMB_CHECK(i == 0 || s.classes[i - 1] < s.classes[i],
                "boost model: stump " << m << " sharing set not sorted/unique");
    }
  }
}

std::string serialize_boost_model(const BoostModel& model) {
  std::ostringstream os(std::ios::binary);
  {
    cereal::PortableBinaryOutputArchive ar(os);
    ar(model);
  }
  return os.str();
}

BoostModel deserialize_boost_model(const std::string& bytes, const std::string& what) {
  BoostModel model;
  try {
    BoundedReader r(bytes, what);
    r.value(model.num_dims);
    r.value(model.num_classes);
    r.vector(model.class_landmark, "class_landmark");
    r.vector(model.bias, "bias");
    // A stump takes at least dim + theta + a + b + size = 29 bytes.
    model.stumps.resize(r.count(29, "stumps"));
    for (SharedStump& s : model.stumps) {
      r.value(s.dim);
      r.value(s.theta);
      r.value(s.a);
      r.value(s.b);
      r.vector(s.classes, "stump classes");
    }
  } catch (const cereal::Exception& e) {
    LMB_FAIL(what << ": truncated or corrupt boost model (" << e.what() << ")");
  }
  model.check();
  return model;
}

void save_trained_model(const std::filesystem::path& path, const BoostModel& model, const FeatureSpace& space) {
  model.check();
  LMB_CHECK(model.num_dims == space.num_dims, path.string() << ": the model has " << model.num_dims
                                                            << " feature dims, its feature space " << space.num_dims);
  std::ostringstream os(std::ios::binary);
  {
    cereal::PortableBinaryOutputArchive ar(os);
    write_byte_string(ar, serialize_boost_model(model));
    write_feature_space(ar, space);
  }
  write_container_file(path, kMagic, kVersion, os.str());
}

TrainedModel load_trained_model(const std::filesystem::path& path) {
  const std::string name = path.string();
  const std::string bytes = read_file(path);
  if (bytes.size() >= kContainerHeaderBytes && bytes.compare(0, 8, kMagic) == 0 && bytes[8] == 1 && bytes[9] == 0 &&
      bytes[10] == 0 && bytes[11] == 0) {
    LMB_FAIL(name << ": a model.bin of an older lboost (format version 1), which does not record the context "
                     "regions, vocabulary and map it was trained with, so export cannot prove they match; "
                     "retrain it (or export it with the lboost that trained it)");
  }
  const std::string payload =
      open_container(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), kMagic, kVersion, name);
  TrainedModel t;
  try {
    BoundedReader r(payload, name);
    t.model = deserialize_boost_model(r.byte_string("model"), name);
    t.feature_space = read_feature_space(r);
    r.expect_end();
  } catch (const cereal::Exception& e) {
    LMB_FAIL(name << ": truncated or corrupt model file (" << e.what() << ")");
  }
  LMB_CHECK(t.model.num_dims == t.feature_space.num_dims, name << ": the model has " << t.model.num_dims
                                                               << " feature dims, its feature space "
                                                               << t.feature_space.num_dims);
  return t;
}

}  // namespace lmb
