#include "train/boost/boost_model.h"

#include <cmath>
#include <sstream>

#include <cereal/archives/portable_binary.hpp>
#include <cereal/types/vector.hpp>

#include "common/error.h"
#include "common/file_container.h"

namespace lmb {

namespace {
constexpr char kMagic[] = "LMBBOOST";
constexpr uint32_t kVersion = 1;
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
  LMB_CHECK(num_classes >= 1 && num_dims >= 1, "boost model: empty (" << num_classes << " classes, "
                                                                       << num_dims << " dims)");
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
    LMB_CHECK(s.dim >= 0 && s.dim < num_dims, "boost model: stump " << m << " dim " << s.dim
                                                                    << " outside [0, " << num_dims << ")");
    for (size_t i = 0; i < s.classes.size(); ++i) {
      LMB_CHECK(s.classes[i] >= 0 && s.classes[i] <= num_classes,
                "boost model: stump " << m << " shares class " << s.classes[i] << " out of range");
      LMB_CHECK(i == 0 || s.classes[i - 1] < s.classes[i], "boost model: stump " << m
                                                                << " sharing set not sorted/unique");
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

namespace {
// Bounds every count against the bytes left before anything is allocated (cereal trusts sizes).
class BoundedReader {
 public:
  BoundedReader(const std::string& bytes, const std::string& what) : is_(bytes), ar_(is_), total_(bytes.size()), what_(what) {}
  template <class T>
  void value(T& x) { ar_(x); }
  uint64_t count(size_t element_bytes) {
    uint64_t n = 0;
    ar_(cereal::make_size_tag(n));
    const auto pos = static_cast<uint64_t>(is_.tellg());
    LMB_CHECK(pos <= total_ && n <= (total_ - pos) / element_bytes,
              what_ << ": corrupt count " << n << " exceeds the " << (total_ - pos) << " bytes left");
    return n;
  }
  template <class T>
  void vector(std::vector<T>& v) {
    v.resize(count(sizeof(T)));
    for (auto& x : v) ar_(x);
  }
 private:
  std::istringstream is_;
  cereal::PortableBinaryInputArchive ar_;
  uint64_t total_;
  std::string what_;
};
}  // namespace

BoostModel deserialize_boost_model(const std::string& bytes, const std::string& what) {
  BoostModel model;
  try {
    BoundedReader r(bytes, what);
    r.value(model.num_dims);
    r.value(model.num_classes);
    r.vector(model.class_landmark);
    r.vector(model.bias);
    // A stump takes at least dim + theta + a + b + size = 29 bytes.
    model.stumps.resize(r.count(29));
    for (SharedStump& s : model.stumps) {
      r.value(s.dim);
      r.value(s.theta);
      r.value(s.a);
      r.value(s.b);
      r.vector(s.classes);
    }
  } catch (const cereal::Exception& e) {
    LMB_FAIL(what << ": truncated or corrupt boost model (" << e.what() << ")");
  }
  model.check();
  return model;
}

void save_boost_model(const std::filesystem::path& path, const BoostModel& model) {
  model.check();
  write_container_file(path, kMagic, kVersion, serialize_boost_model(model));
}

BoostModel load_boost_model(const std::filesystem::path& path) {
  return deserialize_boost_model(read_container_file(path, kMagic, kVersion), path.string());
}

}  // namespace lmb
