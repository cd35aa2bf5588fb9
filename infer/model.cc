#include "infer/model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <cereal/archives/portable_binary.hpp>

#include "common/bounded_reader.h"
#include "common/error.h"
#include "common/file_container.h"
#include "common/hamming.h"

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

}  // namespace

void ModelData::check(const std::string& where) const {
  LMB_CHECK(descriptor_bytes >= 1 && descriptor_bytes <= kMaxDescriptorBytes,
            where << ": descriptor_bytes = " << descriptor_bytes << " outside 1.." << kMaxDescriptorBytes);
  LMB_CHECK(vocabulary.num_words() >= kMinVocabularyWords, where << ": vocabulary is empty");
  LMB_CHECK(vocabulary.descriptor_bytes() == descriptor_bytes,
            where << ": vocabulary has " << vocabulary.descriptor_bytes() << "-byte words, descriptors have "
                  << descriptor_bytes << " bytes");
  regions.validate(where + ": regions");
  const EmbeddingLayout l = layout();
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
}

uint32_t model_file_version(const ModelData& data) {
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
    if (version == kModelVersion) ar(static_cast<uint8_t>(data.fusion.enabled() ? 1 : 0));
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
  }
  return os.str();
}

ModelData parse_model_data(const std::string& payload, const std::string& what, uint32_t version) {
  LMB_CHECK(version == kModelVersion || version == kModelVersionWithFusion || version == kModelVersionWithoutFusion,
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
    if (version == kModelVersion) {
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
    if (version == kModelVersion) {
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
    LMB_CHECK(r.bytes_left() == 0, what << ": " << r.bytes_left() << " unexpected bytes after the model");
  } catch (const cereal::Exception& e) {
    LMB_FAIL(what << ": truncated or corrupt model payload (" << e.what() << ")");
  }
  d.check(what);
  return d;
}

Model::Model(ModelData data) : data_(std::move(data)) {
  data_.check("model");
  layout_ = data_.layout();
  const int32_t C = data_.num_classes;
  const size_t M = data_.stumps.size();

  for (const SharedStump& s : data_.stumps) used_dims_.push_back(s.dim);
  std::sort(used_dims_.begin(), used_dims_.end());
  used_dims_.erase(std::unique(used_dims_.begin(), used_dims_.end()), used_dims_.end());

  dense_stumps_.resize(M);
  stump_class_begin_.assign(M + 1, 0);
  std::vector<int64_t> class_count(static_cast<size_t>(C) + 1, 0);
  for (size_t m = 0; m < M; ++m) {
    const SharedStump& s = data_.stumps[m];
    DenseStump& d = dense_stumps_[m];
    d.used = static_cast<int32_t>(std::lower_bound(used_dims_.begin(), used_dims_.end(), s.dim) - used_dims_.begin());
    d.theta = s.theta;
    d.above = s.a + s.b;  // BoostModel: (fires ? a : 0.0) + b, the same double
    d.below = s.b;
    stump_class_begin_[m + 1] = stump_class_begin_[m] + static_cast<int64_t>(s.classes.size());
    stump_classes_.insert(stump_classes_.end(), s.classes.begin(), s.classes.end());
    for (int32_t c : s.classes) ++class_count[c];
  }

  class_stump_begin_.assign(static_cast<size_t>(C) + 2, 0);
  for (int32_t c = 0; c <= C; ++c) class_stump_begin_[c + 1] = class_stump_begin_[c] + class_count[c];
  class_stumps_.resize(static_cast<size_t>(class_stump_begin_[C + 1]));
  class_stump_index_.resize(class_stumps_.size());
  std::vector<int64_t> fill(class_stump_begin_.begin(), class_stump_begin_.end() - 1);
  for (size_t m = 0; m < M; ++m) {
    for (int32_t c : data_.stumps[m].classes) {
      class_stump_index_[fill[c]] = static_cast<int32_t>(m);
      class_stumps_[fill[c]++] = dense_stumps_[m];
    }
  }

  const int32_t W = data_.vocabulary.num_words();
  word_class_begin_.assign(static_cast<size_t>(W) + 1, 0);
  word_used_begin_.assign(static_cast<size_t>(W) + 1, 0);
  std::vector<uint8_t> mark(used_dims_.size());
  for (int32_t w = 0; w < W; ++w) {
    const std::vector<int32_t>& list = data_.inverted_file[w];
    word_classes_.insert(word_classes_.end(), list.begin(), list.end());
    word_class_begin_[w + 1] = static_cast<int32_t>(word_classes_.size());
    std::fill(mark.begin(), mark.end(), 0);
    auto mark_class = [&](int32_t c) {
      for (int64_t e = class_stump_begin_[c]; e < class_stump_begin_[c + 1]; ++e) {
        mark[class_stumps_[e].used] = 1;
      }
    };
    for (int32_t c : list) mark_class(c);
    mark_class(C);  // the background is always scored
    for (size_t u = 0; u < mark.size(); ++u) {
      if (mark[u]) {
        word_used_.push_back(static_cast<int32_t>(u));
        word_used_dims_.push_back(used_dims_[u]);
      }
    }
    word_used_begin_[w + 1] = static_cast<int32_t>(word_used_.size());
    word_plans_.emplace_back(
        data_.regions, layout_,
        std::vector<int32_t>(word_used_dims_.begin() + word_used_begin_[w], word_used_dims_.end()));
  }
  used_plan_ = DimPlan(data_.regions, layout_, used_dims_);
  if (data_.fusion.enabled()) {
    fusion_max_ = *std::max_element(data_.fusion.distance_score.begin(), data_.fusion.distance_score.end());
  }
  build_screen();
}

double Model::fusion_term(int32_t cls, const uint8_t* descriptor) const {
  if (!data_.fusion.enabled()) return 0.0;
  const DescriptorFusion& f = data_.fusion;
  const int32_t bytes = data_.descriptor_bytes;
  const int64_t first = f.exemplar_begin[cls];
  const int d = hamming_min(descriptor, f.exemplars.data() + first * bytes, f.exemplar_begin[cls + 1] - first, bytes);
  return f.distance_score[d];
}

// Why offset_c + step * x bounds the exact score F of class c from above, x = t at the end, or
// t_k + add_ck at checkpoint k (u = 2^-53, n = the class's stumps, h_i = above_i or below_i its
// outputs in training order):
//   F is the chain F_0 = bias, F_i = fl(F_{i-1} + h_i); every |F_i| <= G (1 + u)^n with
//   G = |bias| + sum (|above_i| + |below_i|), so F <= S + 2 n u G, S the exact real sum.
//   S = bias + sum below_i + sum fires_i (step q_i + r_i), r_i = above_i - below_i - step q_i
//     <= bias + sum below_i + sum max(0, r_i) + step Q, and Q = low + t; at checkpoint k,
//   Q <= Q_k + (the positive q of the remaining stumps) = low + t_k + add_ck.
//   offset_c is bias + sum below_i + sum max(0, r_i) + step low computed in doubles (n + 3 terms,
//   each within 3u of its real value relative to its magnitude) plus a slack; the run-time sum
//   offset + step x (x < 2^17, step x exact) rounds once more. Every error is at most
//   (4 n + 16) u H with H = G + sum (|below_i| + 2 step |q_i| + max(0, r_i)) + step 2^17 +
//   |offset terms| (`magnitude`), so the slack 2 (8 n + 32) u H covers them with room (H is a sum
//   of non-negative doubles, within (n + 8) u of exact).
void Model::build_screen() {
  const int32_t C = data_.num_classes;
  const size_t M = dense_stumps_.size();
  std::vector<double> step_of(M);
  double max_class_sum = 0.0;
  for (size_t m = 0; m < M; ++m) step_of[m] = std::fabs(dense_stumps_[m].above - dense_stumps_[m].below);
  for (int32_t c = 0; c < C; ++c) {
    double sum = 0.0;
    for (int64_t e = class_stump_begin_[c]; e < class_stump_begin_[c + 1]; ++e) {
      sum += step_of[class_stump_index_[e]];
    }
    max_class_sum = std::max(max_class_sum, sum);
  }
  // The smallest power of two with every |q_m| <= 32767 and every class's sum of |q| <= 65535
  // (all q = 0 when the steps overflow: then every bound is +inf and nothing is skipped).
  int exponent = -1000;
  if (max_class_sum > 0.0) exponent = std::max(exponent, std::ilogb(max_class_sum / 65000.0));
  std::vector<int64_t> q(M, 0);
  for (; std::isfinite(max_class_sum) && exponent <= 1023; ++exponent) {
    const double step = std::ldexp(1.0, exponent);
    bool fits = true;
    for (size_t m = 0; m < M && fits; ++m) {
      // Only stumps of some landmark class are screened (the background is always scored exactly).
      const std::vector<int32_t>& members = data_.stumps[m].classes;
      const double r =
          members.front() < C ? std::nearbyint((dense_stumps_[m].above - dense_stumps_[m].below) / step) : 0.0;
      fits = std::fabs(r) <= 32767.0;
      q[m] = fits ? static_cast<int64_t>(r) : 0;
    }
    for (int32_t c = 0; c < C && fits; ++c) {
      int64_t sum = 0;
      for (int64_t e = class_stump_begin_[c]; e < class_stump_begin_[c + 1]; ++e) {
        sum += std::abs(q[class_stump_index_[e]]);
      }
      fits = sum <= 65535;
    }
    if (fits) break;
  }
  const bool usable = std::isfinite(max_class_sum) && exponent <= 1023 && M <= 65536;
  if (!usable) std::fill(q.begin(), q.end(), 0);
  screen_step_ = usable ? std::ldexp(1.0, exponent) : 1.0;
  screen_q_.assign(q.begin(), q.end());
  screen_offset_.resize(static_cast<size_t>(C));
  screen_units_.resize(static_cast<size_t>(C));
  screen_low_.resize(static_cast<size_t>(C));
  // The screening lists: every class's stumps by decreasing |q| (ties: training order), filled
  // from one global order of the stumps.
  std::vector<int32_t> by_step(M);
  for (size_t m = 0; m < M; ++m) by_step[m] = static_cast<int32_t>(m);
  std::stable_sort(by_step.begin(), by_step.end(),
                   [&](int32_t x, int32_t y) { return std::abs(q[x]) > std::abs(q[y]); });
  std::vector<int32_t> list_of(class_stump_index_.size());
  {
    std::vector<int64_t> fill(class_stump_begin_.begin(), class_stump_begin_.end() - 1);
    for (int32_t m : by_step) {
      for (int32_t c : data_.stumps[m].classes) list_of[fill[c]++] = m;
    }
  }
  screen_list_.resize(list_of.size());
  for (size_t e = 0; e < list_of.size(); ++e) screen_list_[e] = usable ? static_cast<uint16_t>(list_of[e]) : 0;
  screen_check_begin_.assign(static_cast<size_t>(C) + 1, 0);
  const double u = std::ldexp(1.0, -53);
  for (int32_t c = 0; c < C; ++c) {
    const int64_t first = class_stump_begin_[c], n = class_stump_begin_[c + 1] - first;
    const double bias = data_.bias[c];
    // The run-time multiple of step is below 2 * 65536 (t_k < 2^16, add_ck <= sum of |q| <= 65535).
    double constant = bias, magnitude = std::fabs(bias) + screen_step_ * 131072.0;
    int64_t low = 0, high = 0;
    for (int64_t e = first; e < first + n; ++e) {
      const int32_t m = class_stump_index_[e];
      const DenseStump& st = dense_stumps_[m];
      const double stepped = screen_step_ * static_cast<double>(q[m]);
      const double rest = std::max(0.0, st.above - st.below - stepped);
      constant += st.below + rest;
      magnitude += std::fabs(st.above) + 2.0 * std::fabs(st.below) + 2.0 * std::fabs(stepped) + rest;
      low += std::min<int64_t>(0, q[m]);
      high += std::max<int64_t>(0, q[m]);
    }
    // The checkpoints of the screening list: prefix sums of the negative q, suffix sums of the
    // positive ones.
    const int32_t* list = list_of.data() + first;
    int64_t prefix_low = 0, suffix_high = high;
    for (int64_t k = 1; k * kScreenCheck < n; ++k) {
      for (int64_t i = (k - 1) * kScreenCheck; i < k * kScreenCheck; ++i) {
        prefix_low += std::min<int64_t>(0, q[list[i]]);
        suffix_high -= std::max<int64_t>(0, q[list[i]]);
      }
      screen_check_low_.push_back(static_cast<uint16_t>(prefix_low & 0xFFFF));
      screen_check_add_.push_back(static_cast<int32_t>(prefix_low - low + suffix_high));
    }
    screen_check_begin_[c + 1] = static_cast<int64_t>(screen_check_low_.size());
    const double stepped_low = screen_step_ * static_cast<double>(low);
    constant += stepped_low;
    magnitude += std::fabs(constant) + std::fabs(stepped_low);
    const double slack = 2.0 * static_cast<double>(8 * n + 32) * u * magnitude;
    // A non-finite bound (overflow) is +inf: the class is always scored exactly.
    const double bound = constant + slack;
    screen_offset_[c] = usable && std::isfinite(bound) ? bound : std::numeric_limits<double>::infinity();
    screen_low_[c] = static_cast<uint16_t>(low & 0xFFFF);
    // offset_c in steps, rounded up and clamped (see screen_units() in model.h; +inf and every
    // offset above the clamp give the largest value, whose test always passes).
    const double units = std::ceil(screen_offset_[c] / screen_step_);
    screen_units_[c] = static_cast<int32_t>(std::clamp(units, -double{kScreenUnitsLimit}, double{kScreenUnitsLimit}));
  }
}

std::shared_ptr<const Model> Model::load(const std::filesystem::path& path) {
  uint32_t version = 0;
  const std::string payload =
      read_container_file(path, kModelMagic, kModelVersionWithoutFusion, kModelVersion, &version);
  return std::make_shared<const Model>(parse_model_data(payload, path.string(), version));
}

std::shared_ptr<const Model> Model::from_bytes(const uint8_t* data, size_t size, const std::string& what) {
  LMB_CHECK(data != nullptr || size == 0, what << ": null buffer");
  uint32_t version = 0;
  const std::string payload =
      open_container(data, size, kModelMagic, kModelVersionWithoutFusion, kModelVersion, what, &version);
  return std::make_shared<const Model>(parse_model_data(payload, what, version));
}

void Model::save(const std::filesystem::path& path) const {
  write_container_file(path, kModelMagic, model_file_version(data_), serialize_model_data(data_));
}

std::vector<uint8_t> Model::to_bytes() const {
  return make_container(kModelMagic, model_file_version(data_), serialize_model_data(data_));
}

}  // namespace lmb
