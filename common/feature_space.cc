#include "common/feature_space.h"

#include <bit>
#include <cstring>
#include <iomanip>
#include <sstream>

#include <cereal/archives/portable_binary.hpp>

#include "common/bounded_reader.h"
#include "common/error.h"

namespace lmb {

namespace {

// A streaming 64-bit hash over little-endian words: every word is scrambled (splitmix64's
// finalizer, a bijection) and folded into the state by xor, rotation and an odd multiply.
class Hasher {
 public:
  void word(uint64_t w) {
    w += 0x9E3779B97F4A7C15ull;
    w = (w ^ (w >> 30)) * 0xBF58476D1CE4E5B9ull;
    w = (w ^ (w >> 27)) * 0x94D049BB133111EBull;
    w ^= w >> 31;
    state_ = std::rotl(state_ ^ w, 23) * 0xFF51AFD7ED558CCDull + 0xC4CEB9FE1A85EC53ull;
  }
  void bytes(const void* data, size_t n) {
    word(n);
    const auto* p = static_cast<const uint8_t*>(data);
    size_t i = 0;
    for (; i + 8 <= n; i += 8) word(load_le(p + i, 8));
    if (i < n) word(load_le(p + i, n - i));
  }
  void text(const std::string& s) { bytes(s.data(), s.size()); }
  void f64(double v) { word(std::bit_cast<uint64_t>(v)); }
  void f32(float v) { word(std::bit_cast<uint32_t>(v)); }
  uint64_t value() const { return state_; }

 private:
  static uint64_t load_le(const uint8_t* p, size_t n) {
    uint64_t w = 0;
    if constexpr (std::endian::native == std::endian::little) {
      std::memcpy(&w, p, n);
    } else {
      for (size_t k = 0; k < n; ++k) w |= static_cast<uint64_t>(p[k]) << (8 * k);
    }
    return w;
  }
  uint64_t state_ = 0x6C6D622D66733031ull;  // "lmb-fs01"
};

std::string hex(uint64_t v) {
  std::ostringstream os;
  os << std::hex << std::setw(16) << std::setfill('0') << v;
  return os.str();
}

std::string describe_regions(const ContextRegions& r) {
  std::ostringstream os;
  os << r.size() << " regions of seed " << r.options().seed;
  return os.str();
}

}  // namespace

uint64_t fingerprint_vocabulary(const Vocabulary& vocabulary) {
  Hasher h;
  h.word(static_cast<uint64_t>(vocabulary.num_words()));
  h.word(static_cast<uint64_t>(vocabulary.descriptor_bytes()));
  h.bytes(vocabulary.words().data(), vocabulary.words().size());
  return h.value();
}

uint64_t fingerprint_map(const LandmarkMap& map) {
  Hasher h;
  h.text(map.detector);
  h.word(static_cast<uint64_t>(map.descriptor_bytes));
  h.word(map.cameras.size());
  for (const Camera& c : map.cameras) {
    h.word(static_cast<uint64_t>(c.model));
    h.word(static_cast<uint64_t>(c.width));
    h.word(static_cast<uint64_t>(c.height));
    h.word(c.params.size());
    for (double p : c.params) h.f64(p);
  }
  h.word(map.frames.size());
  for (const MapFrame& f : map.frames) {
    h.text(f.name);
    h.word(static_cast<uint64_t>(f.camera));
    const Eigen::Quaterniond& q = f.cam_from_world.rotation;
    for (double v : {q.w(), q.x(), q.y(), q.z()}) h.f64(v);
    for (int k = 0; k < 3; ++k) h.f64(f.cam_from_world.translation[k]);
    for (int k = 0; k < 3; ++k) h.f64(f.gravity_in_cam[k]);
    h.word(f.is_query ? 1 : 0);
    h.word(static_cast<uint64_t>(f.first_keypoint));
    h.word(static_cast<uint64_t>(f.num_keypoints));
  }
  h.word(map.keypoints.size());
  for (const Keypoint& k : map.keypoints) {
    h.f32(k.x);
    h.f32(k.y);
    h.f32(k.scale);
    h.f32(k.angle);
  }
  h.bytes(map.descriptors.data(), map.descriptors.size());
  h.word(map.keypoint_landmark.size());
  for (landmark_t l : map.keypoint_landmark) h.word(static_cast<uint64_t>(l));
  h.word(map.landmarks.size());
  for (const Landmark& l : map.landmarks) {
    for (int k = 0; k < 3; ++k) h.f64(l.position[k]);
    h.f32(l.quality);
    h.f32(l.mean_reprojection_error);
    h.word(static_cast<uint64_t>(l.num_map_observations));
    h.word(static_cast<uint64_t>(l.num_query_observations));
  }
  return h.value();
}

FeatureSpace map_feature_space(const ContextRegions& regions, const Vocabulary& vocabulary, const LandmarkMap& map) {
  FeatureSpace s;
  s.regions = regions;
  s.num_words = vocabulary.num_words();
  s.descriptor_bytes = map.descriptor_bytes;
  s.num_dims = regions.size() * vocabulary.num_words() + 8 * map.descriptor_bytes;
  s.vocabulary_fingerprint = fingerprint_vocabulary(vocabulary);
  s.map_fingerprint = fingerprint_map(map);
  s.map_landmarks = static_cast<int64_t>(map.landmarks.size());
  s.map_keypoints = static_cast<int64_t>(map.keypoints.size());
  return s;
}

FeatureSpace synthetic_feature_space(const std::string& name, int32_t num_dims) {
  LMB_CHECK(!name.empty(), "synthetic feature space: empty name");
  FeatureSpace s;
  s.synthetic = name;
  s.num_dims = num_dims;
  return s;
}

std::string feature_space_difference(const FeatureSpace& trained, const FeatureSpace& now) {
  if (trained.is_synthetic() || now.is_synthetic()) {
    if (trained.synthetic == now.synthetic && trained.num_dims == now.num_dims) return "";
    auto what = [](const FeatureSpace& s) {
      return s.is_synthetic() ? "the synthetic problem '" + s.synthetic + "'" : std::string("a map");
    };
    return "the training data differ (training: " + what(trained) + "; now: " + what(now) + ")";
  }
  if (!(trained.regions == now.regions)) {
    return "the context regions differ (training: " + describe_regions(trained.regions) +
           "; now: " + describe_regions(now.regions) + ")";
  }
  if (trained.vocabulary_fingerprint != now.vocabulary_fingerprint || trained.num_words != now.num_words) {
    return "the vocabulary differs (training: " + std::to_string(trained.num_words) + " words, fingerprint " +
           hex(trained.vocabulary_fingerprint) + "; now: " + std::to_string(now.num_words) + " words, fingerprint " +
           hex(now.vocabulary_fingerprint) + ")";
  }
  if (trained.map_fingerprint != now.map_fingerprint || trained.descriptor_bytes != now.descriptor_bytes) {
    return "the map differs (training: " + std::to_string(trained.map_landmarks) + " landmarks, " +
           std::to_string(trained.map_keypoints) + " keypoints, fingerprint " + hex(trained.map_fingerprint) +
           "; now: " + std::to_string(now.map_landmarks) + " landmarks, " + std::to_string(now.map_keypoints) +
           " keypoints, fingerprint " + hex(now.map_fingerprint) + ")";
  }
  if (trained.num_dims != now.num_dims) {
    return "the feature dimension differs (training: " + std::to_string(trained.num_dims) +
           "; now: " + std::to_string(now.num_dims) + ")";
  }
  return "";
}

void write_feature_space(cereal::PortableBinaryOutputArchive& ar, const FeatureSpace& s) {
  write_byte_string(ar, s.synthetic);
  ar(s.num_dims);
  if (s.is_synthetic()) return;
  write_context_regions(ar, s.regions);
  ar(s.num_words, s.descriptor_bytes, s.vocabulary_fingerprint, s.map_fingerprint, s.map_landmarks, s.map_keypoints);
}

FeatureSpace read_feature_space(BoundedReader& r) {
  FeatureSpace s;
  s.synthetic = r.byte_string("feature space name", 256);
  r.value(s.num_dims);
  LMB_CHECK(s.num_dims >= 1, r.what() << ": feature space: num_dims = " << s.num_dims << " must be >= 1");
  if (s.is_synthetic()) return s;
  s.regions = read_context_regions(r);
  r.value(s.num_words);
  r.value(s.descriptor_bytes);
  r.value(s.vocabulary_fingerprint);
  r.value(s.map_fingerprint);
  r.value(s.map_landmarks);
  r.value(s.map_keypoints);
  LMB_CHECK(s.num_words >= kMinVocabularyWords && s.num_words <= kMaxVocabularyWords,
            r.what() << ": feature space: num_words = " << s.num_words << " outside " << kMinVocabularyWords << ".."
                     << kMaxVocabularyWords);
  LMB_CHECK(s.descriptor_bytes >= 1 && s.descriptor_bytes <= kMaxDescriptorBytes,
            r.what() << ": feature space: descriptor_bytes = " << s.descriptor_bytes << " outside 1.."
                     << kMaxDescriptorBytes);
  const int64_t dims = int64_t{s.regions.size()} * s.num_words + 8 * int64_t{s.descriptor_bytes};
  LMB_CHECK(dims == s.num_dims, r.what() << ": feature space: num_dims = " << s.num_dims << ", but " << s.regions.size()
                                         << " regions x " << s.num_words << " words + " << 8 * s.descriptor_bytes
                                         << " bits = " << dims);
  return s;
}

std::string serialize_feature_space(const FeatureSpace& space) {
  std::ostringstream os(std::ios::binary);
  {
    cereal::PortableBinaryOutputArchive ar(os);
    write_feature_space(ar, space);
  }
  return os.str();
}

FeatureSpace parse_feature_space(const std::string& bytes, const std::string& what) {
  try {
    BoundedReader r(bytes, what);
    FeatureSpace s = read_feature_space(r);
    r.expect_end();
    return s;
  } catch (const cereal::Exception& e) {
    LMB_FAIL(what << ": truncated or corrupt feature space (" << e.what() << ")");
  }
}

}  // namespace lmb
