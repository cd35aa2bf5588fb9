#include "infer/model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <cereal/archives/portable_binary.hpp>

#include "common/bounded_reader.h"
#include "common/error.h"
#include "common/file_container.h"
#include "infer/detail/model_format.h"
#include "infer/detail/scoring_index.h"

namespace lmb {

namespace detail {

std::string encode_ascending_ids(const std::vector<int32_t>& ids) {
  std::string out;
  out.reserve(ids.size() * 2);
  uint32_t prev = 0;
  for (size_t i = 0; i < ids.size(); ++i) {
    uint32_t gap = static_cast<uint32_t>(ids[i]) - (i == 0 ? 0u : prev);
    prev = static_cast<uint32_t>(ids[i]);
    do {
      uint8_t byte = gap & 0x7F;
      gap >>= 7;
      if (gap != 0) byte |= 0x80;
      out.push_back(static_cast<char>(byte));
    } while (gap != 0);
  }
  return out;
}

std::vector<int32_t> decode_ascending_ids(const std::string& bytes, uint32_t count, int32_t max_id,
                                          const std::string& what) {
  // Every id takes at least one byte: a count above the byte count is corrupt (checked before
  // allocating).
  LMB_CHECK(count <= bytes.size(), what << ": corrupt id list: " << count << " ids in " << bytes.size() << " bytes");
  std::vector<int32_t> ids(count);
  size_t pos = 0;
  int64_t prev = -1;
  for (uint32_t i = 0; i < count; ++i) {
    uint64_t gap = 0;
    int shift = 0;
    while (true) {
      LMB_CHECK(pos < bytes.size(), what << ": corrupt id list: ends inside id " << i);
      const uint8_t byte = static_cast<uint8_t>(bytes[pos++]);
      gap |= static_cast<uint64_t>(byte & 0x7F) << shift;
      if ((byte & 0x80) == 0) break;
      shift += 7;
      LMB_CHECK(shift <= 28, what << ": corrupt id list: varint too long at id " << i);
    }
    LMB_CHECK(i == 0 || gap > 0, what << ": corrupt id list: ids not strictly ascending at " << i);
    const int64_t id = (i == 0 ? 0 : prev) + static_cast<int64_t>(gap);
    LMB_CHECK(id <= max_id, what << ": corrupt id list: id " << id << " exceeds " << max_id);
    ids[i] = static_cast<int32_t>(id);
    prev = id;
  }
  LMB_CHECK(pos == bytes.size(),
            what << ": corrupt id list: " << bytes.size() - pos << " extra bytes after " << count << " ids");
  return ids;
}

}  // namespace detail

namespace {

constexpr size_t kMaxDetectorNameBytes = 256;

void check_ascending(const std::vector<int32_t>& ids, int32_t lo, int32_t hi_inclusive, const std::string& where) {
  for (size_t i = 0; i < ids.size(); ++i) {
    LMB_CHECK(ids[i] >= lo && ids[i] <= hi_inclusive,
              where << ": class " << ids[i] << " outside " << lo << ".." << hi_inclusive);
    LMB_CHECK(i == 0 || ids[i - 1] < ids[i], where << ": classes not strictly ascending");
  }
}

WalkCalibration read_walk_calibration(BoundedReader& r, const std::string& what, uint32_t version) {
  WalkCalibration c;
  uint32_t features = 0;
  r.value(features);
  LMB_CHECK(features == static_cast<uint32_t>(WalkEvidence::kNumFeatures),
            what << ": walk calibration: " << features << " features, expected " << WalkEvidence::kNumFeatures);
  for (double& w : c.weights) r.value(w);
  r.value(c.bias);
  r.value(c.threshold);
  r.value(c.translation_scale_m);
  r.value(c.rotation_scale_deg);
  r.value(c.max_gap);
  r.value(c.num_samples);
  r.value(c.num_positive);
  r.value(c.target_precision);
  if (version >= kModelVersionWithAgreement) {
    uint8_t adds = 0;
    r.value(adds);
    LMB_CHECK(adds <= 1, what << ": walk calibration: adds = " << static_cast<int>(adds) << " is not 0 or 1");
    c.adds = adds == 1;
    r.value(c.agreement_noise_m);
    r.value(c.agreement_noise_deg);
    r.value(c.agreement_step_m);
    r.value(c.agreement_step_deg);
  }
  return c;
}

}  // namespace

void ModelData::check(const std::string& where) const {
  LMB_CHECK(descriptor_bytes >= 1 && descriptor_bytes <= kMaxDescriptorBytes,
            where << ": descriptor_bytes = " << descriptor_bytes << " outside 1.." << kMaxDescriptorBytes);
  LMB_CHECK(vocabulary.num_words() >= kMinVocabularyWords, where << ": vocabulary is empty");
  LMB_CHECK(vocabulary.descriptor_bytes() == descriptor_bytes,
            where << ": vocabulary has " << vocabulary.descriptor_bytes() << "-byte words, descriptors have "
                  << descriptor_bytes << " bytes");
  regions.validate(where + ": regions");
  const EmbeddingLayout l = detail::layout_of(*this);
  l.check();
  LMB_CHECK(num_classes >= 1, where << ": num_classes = " << num_classes << " must be >= 1");
  const size_t C = static_cast<size_t>(num_classes);
  LMB_CHECK(class_landmark.size() == C,
            where << ": class_landmark has " << class_landmark.size() << " entries, expected " << C);
  LMB_CHECK(class_position.size() == C,
            where << ": class_position has " << class_position.size() << " entries, expected " << C);
  for (size_t c = 0; c < C; ++c) {
    LMB_CHECK(class_landmark[c] >= 0, where << ": class " << c << " has landmark id " << class_landmark[c]);
    LMB_CHECK(class_position[c].allFinite(), where << ": class " << c << " has a non-finite position");
  }
  LMB_CHECK(bias.size() == C + 1, where << ": bias has " << bias.size() << " entries, expected " << C + 1);
  for (size_t c = 0; c <= C; ++c) {
    LMB_CHECK(std::isfinite(bias[c]), where << ": class " << c << " has a non-finite bias");
  }
  for (size_t m = 0; m < stumps.size(); ++m) {
    const SharedStump& s = stumps[m];
    const std::string sw = where + ": stump " + std::to_string(m);
    LMB_CHECK(s.dim >= 0 && s.dim < l.num_dims(), sw << ": dim " << s.dim << " outside [0, " << l.num_dims() << ")");
    LMB_CHECK(s.theta < 255, sw << ": threshold 255 never fires");
    LMB_CHECK(std::isfinite(s.a) && std::isfinite(s.b), sw << ": non-finite a or b");
    LMB_CHECK(!s.classes.empty(), sw << ": empty sharing set");
    check_ascending(s.classes, 0, num_classes, sw);
  }
  LMB_CHECK(static_cast<int32_t>(inverted_file.size()) == vocabulary.num_words(),
            where << ": inverted file has " << inverted_file.size() << " lists, expected " << vocabulary.num_words());
  for (size_t w = 0; w < inverted_file.size(); ++w) {
    check_ascending(inverted_file[w], 0, num_classes - 1, where + ": inverted file word " + std::to_string(w));
  }
  if (fusion.enabled()) {
    const std::string fw = where + ": descriptor fusion";
    LMB_CHECK(fusion.exemplar_begin.size() == C + 1,
              fw << ": exemplar_begin has " << fusion.exemplar_begin.size() << " entries, expected " << C + 1);
    LMB_CHECK(fusion.exemplar_begin[0] == 0, fw << ": exemplar_begin[0] = " << fusion.exemplar_begin[0]);
    for (size_t c = 0; c < C; ++c) {
      LMB_CHECK(fusion.exemplar_begin[c + 1] > fusion.exemplar_begin[c],
                fw << ": class " << c << " has no exemplar (offsets not increasing)");
    }
    const uint64_t rows = static_cast<uint64_t>(fusion.exemplar_begin[C]);
    LMB_CHECK(fusion.exemplars.size() / static_cast<uint64_t>(descriptor_bytes) == rows &&
                  fusion.exemplars.size() % static_cast<uint64_t>(descriptor_bytes) == 0,
              fw << ": " << fusion.exemplars.size() << " exemplar bytes for " << rows << " rows of " << descriptor_bytes
                 << " bytes");
    const size_t distances = 8 * static_cast<size_t>(descriptor_bytes) + 1;
    LMB_CHECK(fusion.distance_score.size() == distances,
              fw << ": distance_score has " << fusion.distance_score.size() << " entries, expected " << distances);
    for (size_t d = 0; d < distances; ++d) {
      LMB_CHECK(std::isfinite(fusion.distance_score[d]), fw << ": distance_score[" << d << "] is not finite");
    }
  }
  if (calibration) calibration->check(where + ": pose calibration");
  if (walk_calibration) {
    LMB_CHECK(calibration.has_value(), where << ": a walk calibration needs a pose calibration");
    walk_calibration->check(where + ": walk calibration");
  }
}

uint32_t model_file_version(const ModelData& data) {
  if (data.walk_calibration) {
    const WalkCalibration& w = *data.walk_calibration;
    return w.has_agreement() || !w.adds ? kModelVersionWithAgreement : kModelVersionWithWalk;
  }
  if (data.calibration) return kModelVersion;
  return data.fusion.enabled() ? kModelVersionWithFusion : kModelVersionWithoutFusion;
}

std::string serialize_model_data(const ModelData& data) {
  data.check("model");
  std::ostringstream os(std::ios::binary);
  {
    cereal::PortableBinaryOutputArchive ar(os);
    write_byte_string(ar, data.detector);
    ar(data.descriptor_bytes);
    write_context_regions(ar, data.regions);
    write_byte_string(ar, data.vocabulary.to_payload());
    ar(data.num_classes);
    ar(static_cast<uint64_t>(data.class_landmark.size()));
    for (landmark_t id : data.class_landmark) ar(static_cast<int64_t>(id));
    ar(static_cast<uint64_t>(data.class_position.size()));
    for (const Eigen::Vector3d& p : data.class_position) ar(p.x(), p.y(), p.z());
    ar(static_cast<uint64_t>(data.bias.size()));
    for (double b : data.bias) ar(b);
    ar(static_cast<uint64_t>(data.stumps.size()));
    for (const SharedStump& s : data.stumps) {
      ar(s.dim, s.theta, s.a, s.b, static_cast<uint32_t>(s.classes.size()));
      write_byte_string(ar, detail::encode_ascending_ids(s.classes));
    }
    ar(static_cast<int32_t>(data.inverted_file.size()));
    for (const std::vector<int32_t>& list : data.inverted_file) {
      ar(static_cast<uint32_t>(list.size()));
      write_byte_string(ar, detail::encode_ascending_ids(list));
    }
    const uint32_t version = model_file_version(data);
    if (version >= kModelVersion) ar(static_cast<uint8_t>(data.fusion.enabled() ? 1 : 0));
    if (data.fusion.enabled()) {
      const DescriptorFusion& f = data.fusion;
      ar(static_cast<uint64_t>(f.exemplar_begin.size()));
      for (int64_t b : f.exemplar_begin) ar(b);
      ar(static_cast<uint64_t>(f.exemplars.size()));
      ar(cereal::binary_data(f.exemplars.data(), f.exemplars.size()));
      ar(static_cast<uint64_t>(f.distance_score.size()));
      for (double v : f.distance_score) ar(v);
    }
    if (data.calibration) {
      const PoseCalibration& c = *data.calibration;
      ar(static_cast<uint32_t>(PoseEvidence::kNumFeatures));
      for (double w : c.weights) ar(w);
      ar(c.bias, c.threshold, c.num_samples, c.num_positive, c.target_precision);
    }
    if (data.walk_calibration) {
      const WalkCalibration& c = *data.walk_calibration;
      ar(static_cast<uint32_t>(WalkEvidence::kNumFeatures));
      for (double w : c.weights) ar(w);
      ar(c.bias, c.threshold, c.translation_scale_m, c.rotation_scale_deg, c.max_gap, c.num_samples, c.num_positive,
         c.target_precision);
      if (version >= kModelVersionWithAgreement) {
        ar(static_cast<uint8_t>(c.adds ? 1 : 0), c.agreement_noise_m, c.agreement_noise_deg, c.agreement_step_m,
           c.agreement_step_deg);
      }
    }
  }
  return os.str();
}

ModelData parse_model_data(const std::string& payload, const std::string& what, uint32_t version) {
  LMB_CHECK(version == kModelVersionWithAgreement || version == kModelVersionWithWalk || version == kModelVersion ||
                version == kModelVersionWithFusion || version == kModelVersionWithoutFusion,
            what << ": model format version " << version << " is not supported");
  ModelData d;
  try {
    BoundedReader r(payload, what);
    d.detector = r.byte_string("detector", kMaxDetectorNameBytes);
    r.value(d.descriptor_bytes);
    d.regions = read_context_regions(r);
    d.vocabulary = Vocabulary::from_payload(r.byte_string("vocabulary"), what + ": vocabulary");
    r.value(d.num_classes);
    LMB_CHECK(d.num_classes >= 1, what << ": num_classes = " << d.num_classes << " must be >= 1");
    d.class_landmark.resize(r.count(sizeof(int64_t), "class_landmark"));
    for (landmark_t& id : d.class_landmark) {
      int64_t v = 0;
      r.value(v);
      id = v;
    }
    d.class_position.resize(r.count(3 * sizeof(double), "class_position"));
    for (Eigen::Vector3d& p : d.class_position) {
      r.value(p.x());
      r.value(p.y());
      r.value(p.z());
    }
    d.bias.resize(r.count(sizeof(double), "bias"));
    for (double& b : d.bias) r.value(b);
    // A stump takes at least dim + theta + a + b + set count + set size = 33 bytes.
    d.stumps.resize(r.count(33, "stumps"));
    for (size_t m = 0; m < d.stumps.size(); ++m) {
      SharedStump& s = d.stumps[m];
      uint32_t n = 0;
      r.value(s.dim);
      r.value(s.theta);
      r.value(s.a);
      r.value(s.b);
      r.value(n);
      s.classes = detail::decode_ascending_ids(r.byte_string("stump classes"), n, d.num_classes,
                                               what + ": stump " + std::to_string(m));
    }
    int32_t num_lists = 0;
    r.value(num_lists);
    LMB_CHECK(num_lists == d.vocabulary.num_words(),
              what << ": inverted file has " << num_lists << " lists, expected " << d.vocabulary.num_words());
    d.inverted_file.resize(static_cast<size_t>(num_lists));
    for (int32_t w = 0; w < num_lists; ++w) {
      uint32_t n = 0;
      r.value(n);
      d.inverted_file[w] = detail::decode_ascending_ids(r.byte_string("inverted file"), n, d.num_classes - 1,
                                                        what + ": inverted file word " + std::to_string(w));
    }
    bool has_fusion = version == kModelVersionWithFusion;
    if (version >= kModelVersion) {
      uint8_t flag = 0;
      r.value(flag);
      LMB_CHECK(flag <= 1, what << ": has_fusion = " << static_cast<int>(flag) << " is not 0 or 1");
      has_fusion = flag == 1;
    }
    if (has_fusion) {
      DescriptorFusion& f = d.fusion;
      f.exemplar_begin.resize(r.count(sizeof(int64_t), "fusion exemplar offsets"));
      LMB_CHECK(f.exemplar_begin.size() == static_cast<size_t>(d.num_classes) + 1,
                what << ": descriptor fusion: " << f.exemplar_begin.size() << " exemplar offsets, expected "
                     << d.num_classes + 1);
      for (int64_t& b : f.exemplar_begin) r.value(b);
      const std::string rows = r.byte_string("fusion exemplars");
      f.exemplars.assign(rows.begin(), rows.end());
      f.distance_score.resize(r.count(sizeof(double), "fusion distance scores"));
      for (double& v : f.distance_score) r.value(v);
    }
    if (version >= kModelVersion) {
      PoseCalibration c;
      uint32_t features = 0;
      r.value(features);
      LMB_CHECK(features == static_cast<uint32_t>(PoseEvidence::kNumFeatures),
                what << ": pose calibration: " << features << " features, expected " << PoseEvidence::kNumFeatures);
      for (double& w : c.weights) r.value(w);
      r.value(c.bias);
      r.value(c.threshold);
      r.value(c.num_samples);
      r.value(c.num_positive);
      r.value(c.target_precision);
      d.calibration = c;
    }
    if (version >= kModelVersionWithWalk) d.walk_calibration = read_walk_calibration(r, what, version);
    LMB_CHECK(r.bytes_left() == 0, what << ": " << r.bytes_left() << " unexpected bytes after the model");
  } catch (const cereal::Exception& e) {
    LMB_FAIL(what << ": truncated or corrupt model payload (" << e.what() << ")");
  }
  d.check(what);
  return d;
}

Model::Model(ModelData data) : data_(std::move(data)) {
  data_.check("model");
  scoring_ = std::make_shared<const detail::ScoringIndex>(data_);
}

std::shared_ptr<const Model> Model::load(const std::filesystem::path& path) {
  uint32_t version = 0;
  const std::string payload =
      read_container_file(path, kModelMagic, kModelVersionWithoutFusion, kModelVersionWithAgreement, &version);
  return std::make_shared<const Model>(parse_model_data(payload, path.string(), version));
}

std::shared_ptr<const Model> Model::from_bytes(const uint8_t* data, size_t size, const std::string& what) {
  LMB_CHECK(data != nullptr || size == 0, what << ": null buffer");
  uint32_t version = 0;
  const std::string payload =
      open_container(data, size, kModelMagic, kModelVersionWithoutFusion, kModelVersionWithAgreement, what, &version);
  return std::make_shared<const Model>(parse_model_data(payload, what, version));
}

void Model::save(const std::filesystem::path& path) const {
  write_container_file(path, kModelMagic, model_file_version(data_), serialize_model_data(data_));
}

std::vector<uint8_t> Model::to_bytes() const {
  return make_container(kModelMagic, model_file_version(data_), serialize_model_data(data_));
}

}  // namespace lmb
