#include "infer/bundle_index.h"

#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <set>
#include <sstream>

#include "common/error.h"
#include "common/file_container.h"
#include "common/file_io.h"
#include "common/text_lines.h"
#include "common/text_parse.h"
#include "infer/model.h"

namespace lmb {

namespace {

uint64_t parse_unsigned(const std::string& token, const std::string& where, const std::string& field, int base,
                        uint64_t max) {
  const char* begin = token.c_str();
  char* end = nullptr;
  errno = 0;
  const unsigned long long v = token.empty() || token[0] == '-' ? 0 : std::strtoull(begin, &end, base);
  LMB_CHECK(!token.empty() && token[0] != '-' && end == begin + token.size() && errno != ERANGE && v <= max,
            where << ": " << field << " is not a number in 0.." << max << ": '" << token << "'");
  return v;
}

uint64_t parse_hex64(const std::string& token, const std::string& where, const std::string& field) {
  LMB_CHECK(token.size() == 16, where << ": " << field << " is not 16 hex digits: '" << token << "'");
  return parse_unsigned(token, where, field, 16, UINT64_MAX);
}

std::string hex64(uint64_t v) {
  char text[24];
  std::snprintf(text, sizeof(text), "%016" PRIx64, v);
  return text;
}

// FNV-1a over 64-bit words.
struct Fnv {
  uint64_t h = 1469598103934665603ull;
  void word(uint64_t v) {
    for (int b = 0; b < 8; ++b) {
      h ^= (v >> (8 * b)) & 0xFF;
      h *= 1099511628211ull;
    }
  }
  void f64(double v) {
    uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof(bits));
    word(bits);
  }
};

// Whether `text` is UTF-8 without control characters.
bool printable_utf8(const std::string& text) {
  size_t i = 0;
  while (i < text.size()) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 || c == 0x7F) return false;
    size_t extra = 0;
    if (c >= 0x80) {
      if ((c >> 5) == 0x6) {
        extra = 1;
      } else if ((c >> 4) == 0xE) {
        extra = 2;
      } else if ((c >> 3) == 0x1E) {
        extra = 3;
      } else {
        return false;
      }
    }
    if (i + extra >= text.size() + (extra == 0 ? 1 : 0)) return false;
    for (size_t k = 1; k <= extra; ++k) {
      if ((static_cast<unsigned char>(text[i + k]) >> 6) != 0x2) return false;
    }
    i += 1 + extra;
  }
  return true;
}

// A file name inside the index's folder: not empty, printable UTF-8, no folder separator or white
// space, not "." or "..".
bool plain_file_name(const std::string& name) {
  return !name.empty() && name != "." && name != ".." && name.find_first_of("/\\ ") == std::string::npos &&
         printable_utf8(name);
}

}  // namespace

double BundleArea::distance(const Eigen::Vector3d& p) const {
  double sq = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double d = p[a] < cell_lo[a] ? cell_lo[a] - p[a] : (p[a] > cell_hi[a] ? p[a] - cell_hi[a] : 0.0);
    sq += d * d;
  }
  return std::sqrt(sq);
}

uint64_t fingerprint_classes(const Model& model) {
  Fnv f;
  f.word(static_cast<uint64_t>(model.num_classes()));
  for (int32_t c = 0; c < model.num_classes(); ++c) {
    f.word(static_cast<uint64_t>(model.class_landmark(c)));
    for (int k = 0; k < 3; ++k) f.f64(model.class_position(c)[k]);
  }
  return f.h;
}

BundleArea describe_area(int32_t id, const std::string& file, const std::string& image, const Model& model) {
  BundleArea a;
  a.id = id;
  a.file = file;
  a.bytes = image.size();
  a.crc32 = crc32(reinterpret_cast<const uint8_t*>(image.data()), image.size());
  a.landmarks = model.num_classes();
  for (int32_t c = 0; c < model.num_classes(); ++c) {
    const landmark_t l = model.class_landmark(c);
    if (c == 0 || l < a.first_landmark) a.first_landmark = l;
    if (c == 0 || l > a.last_landmark) a.last_landmark = l;
  }
  a.classes = fingerprint_classes(model);
  return a;
}

void check_area_model(const BundleArea& area, const Model& model, const std::string& what) {
  LMB_CHECK(model.num_classes() == area.landmarks, what << ": " << model.num_classes()
                                                        << " classes, the bundle index says " << area.landmarks
                                                        << " (a model of another area or map)");
  if (area.classes == 0) return;  // versions 1 and 2 record no more
  const BundleArea got = describe_area(area.id, area.file, std::string(), model);
  LMB_CHECK(got.first_landmark == area.first_landmark && got.last_landmark == area.last_landmark,
            what << ": its classes are landmarks " << got.first_landmark << ".." << got.last_landmark
                 << ", the bundle index says " << area.first_landmark << ".." << area.last_landmark
                 << " (a model of another area or map)");
  LMB_CHECK(got.classes == area.classes, what << ": its classes (landmark ids and positions) differ from the ones "
                                                 "the bundle index records (a model of another area or map)");
}

void check_bundle_index(const BundleIndex& index, const std::string& where) {
  LMB_CHECK(std::isfinite(index.reach) && index.reach >= 0.0,
            where << ": reach " << index.reach << " must be finite and >= 0");
  LMB_CHECK(!index.areas.empty(), where << ": a bundle needs at least one area");
  if (index.calibration) index.calibration->check(where + ": calibration");
  if (index.walk_calibration) {
    LMB_CHECK(index.calibration, where << ": a walk calibration needs the bundle's calibration");
    index.walk_calibration->check(where + ": walk calibration");
  }
  std::set<std::string> files;
  for (size_t i = 0; i < index.areas.size(); ++i) {
    const BundleArea& a = index.areas[i];
    LMB_CHECK(a.id == static_cast<int32_t>(i), where << ": area " << i << " has id " << a.id);
    LMB_CHECK(plain_file_name(a.file),
              where << ": area " << i << ": file '" << a.file << "' is not a plain file name in the bundle folder");
    LMB_CHECK(files.insert(a.file).second, where << ": area " << i << ": file '" << a.file << "' is used twice");
  }
}

void write_bundle_index(const std::filesystem::path& path, const BundleIndex& index) {
  const std::string where = path.string();
  check_bundle_index(index, where);
  LMB_CHECK(index.map_fingerprint != 0, where << ": the map fingerprint is not set");
  std::ostringstream os;
  os << "lmb-bundle " << BundleIndex::kVersion << "\n";
  os << "# area ID file FILE bytes N crc32 HEX landmarks N first_landmark ID last_landmark ID classes HEX cell LO_X "
        "LO_Y LO_Z HI_X HI_Y HI_Z\n";
  os << "reach " << exact_number_text(index.reach) << "\n";
  os << "map " << hex64(index.map_fingerprint) << "\n";
  if (index.calibration) {
    const PoseCalibration& c = *index.calibration;
    os << "# calibration W0..W" << PoseEvidence::kNumFeatures - 1
       << " BIAS THRESHOLD SAMPLES POSITIVE TARGET_PRECISION (infer/pose_confidence.h)\n";
    os << "calibration";
    for (double w : c.weights) os << " " << exact_number_text(w);
    os << " " << exact_number_text(c.bias) << " " << exact_number_text(c.threshold) << " " << c.num_samples << " "
       << c.num_positive << " " << exact_number_text(c.target_precision) << "\n";
  }
  if (index.walk_calibration) {
    const WalkCalibration& c = *index.walk_calibration;
    os << "# walk_calibration W0..W" << WalkEvidence::kNumFeatures - 1
       << " BIAS THRESHOLD TRANSLATION_SCALE_M ROTATION_SCALE_DEG MAX_GAP ADDS NOISE_M NOISE_DEG STEP_M STEP_DEG "
          "SAMPLES POSITIVE TARGET_PRECISION (infer/walk_confidence.h)\n";
    os << "walk_calibration";
    for (double w : c.weights) os << " " << exact_number_text(w);
    for (double v : {c.bias, c.threshold, c.translation_scale_m, c.rotation_scale_deg}) {
      os << " " << exact_number_text(v);
    }
    os << " " << c.max_gap << " " << (c.adds ? 1 : 0);
    for (double v : {c.agreement_noise_m, c.agreement_noise_deg, c.agreement_step_m, c.agreement_step_deg}) {
      os << " " << exact_number_text(v);
    }
    os << " " << c.num_samples << " " << c.num_positive << " " << exact_number_text(c.target_precision) << "\n";
  }
  os << "areas " << index.areas.size() << "\n";
  for (const BundleArea& a : index.areas) {
    LMB_CHECK(a.classes != 0 && a.landmarks >= 1 && a.first_landmark >= 0 && a.first_landmark <= a.last_landmark,
              where << ": area " << a.id << ": its model is not described (describe_area)");
    char crc[16];
    std::snprintf(crc, sizeof(crc), "%08x", a.crc32);
    os << "area " << a.id << " file " << a.file << " bytes " << a.bytes << " crc32 " << crc << " landmarks "
       << a.landmarks << " first_landmark " << a.first_landmark << " last_landmark " << a.last_landmark << " classes "
       << hex64(a.classes) << " cell";
    for (int k = 0; k < 3; ++k) os << " " << exact_number_text(a.cell_lo[k]);
    for (int k = 0; k < 3; ++k) os << " " << exact_number_text(a.cell_hi[k]);
    os << "\n";
  }
  write_file_atomically(path, os.str());
}

namespace {

// One `area` line's tokens (after the key) into `a`; version 3 lines carry the model's description.
BundleArea parse_area(const std::vector<std::string>& t, const std::string& w, int version, uint64_t expected_id,
                      uint64_t num_areas) {
  BundleArea a;
  const uint64_t id = parse_unsigned(t[0], w, "area id", 10, num_areas);
  LMB_CHECK(id == expected_id, w << ": area id " << id << ", expected " << expected_id);
  a.id = static_cast<int32_t>(id);
  std::vector<const char*> names = {"file", "bytes", "crc32", "landmarks"};
  if (version >= 3) names.insert(names.end(), {"first_landmark", "last_landmark", "classes"});
  names.push_back("cell");
  for (size_t k = 0; k < names.size(); ++k) {
    LMB_CHECK(t[1 + 2 * k] == names[k], w << ": expected '" << names[k] << "', found '" << t[1 + 2 * k] << "'");
  }
  a.file = t[2];
  LMB_CHECK(plain_file_name(a.file),
            w << ": file '" << a.file
              << "' must be a file name in the bundle's folder (no folder, no '..', printable UTF-8)");
  a.bytes = parse_unsigned(t[4], w, "bytes", 10, UINT64_MAX);
  LMB_CHECK(t[6].size() == 8, w << ": crc32 is not 8 hex digits: '" << t[6] << "'");
  a.crc32 = static_cast<uint32_t>(parse_unsigned(t[6], w, "crc32", 16, UINT32_MAX));
  a.landmarks = static_cast<int64_t>(parse_unsigned(t[8], w, "landmarks", 10, INT32_MAX));
  size_t at = 9;
  if (version >= 3) {
    LMB_CHECK(a.landmarks >= 1, w << ": landmarks must be at least 1");
    a.first_landmark = static_cast<landmark_t>(parse_unsigned(t[10], w, "first_landmark", 10, INT64_MAX));
    a.last_landmark = static_cast<landmark_t>(parse_unsigned(t[12], w, "last_landmark", 10, INT64_MAX));
    LMB_CHECK(a.first_landmark <= a.last_landmark &&
                  static_cast<uint64_t>(a.last_landmark - a.first_landmark) >= static_cast<uint64_t>(a.landmarks - 1),
              w << ": landmarks " << a.first_landmark << ".." << a.last_landmark << " cannot hold " << a.landmarks
                << " classes");
    a.classes = parse_hex64(t[14], w, "classes");
    LMB_CHECK(a.classes != 0, w << ": classes fingerprint is zero");
    at = 15;
  }
  for (int k = 0; k < 3; ++k) a.cell_lo[k] = parse_number_or_infinity(t[at + 1 + k], w, "cell");
  for (int k = 0; k < 3; ++k) a.cell_hi[k] = parse_number_or_infinity(t[at + 4 + k], w, "cell");
  for (int k = 0; k < 3; ++k) {
    LMB_CHECK(a.cell_lo[k] <= a.cell_hi[k], w << ": cell lower end above its upper end on axis " << k);
    LMB_CHECK(a.cell_lo[k] < std::numeric_limits<double>::infinity() &&
                  a.cell_hi[k] > -std::numeric_limits<double>::infinity(),
              w << ": cell on axis " << k << " lies at infinity");
  }
  return a;
}

// A `walk_calibration` line's tokens (the key first).
WalkCalibration parse_walk_calibration(const std::vector<std::string>& t, const std::string& w,
                                       const std::string& line) {
  constexpr size_t kF = WalkEvidence::kNumFeatures;
  LMB_CHECK(t.size() == kF + 14,
            w << ": expected 'walk_calibration' and " << kF + 13 << " value(s), found '" << line << "'");
  WalkCalibration c;
  size_t at = 1;
  const auto number = [&](const char* what) { return parse_finite_number(t[at++], w, what); };
  for (double& x : c.weights) x = number("walk calibration weight");
  c.bias = number("walk calibration bias");
  c.threshold = number("walk calibration threshold");
  c.translation_scale_m = number("walk calibration translation scale");
  c.rotation_scale_deg = number("walk calibration rotation scale");
  c.max_gap = static_cast<int32_t>(parse_unsigned(t[at++], w, "walk calibration max_gap", 10, 1000));
  c.adds = parse_unsigned(t[at++], w, "walk calibration adds", 10, 1) == 1;
  c.agreement_noise_m = number("walk calibration agreement noise");
  c.agreement_noise_deg = number("walk calibration agreement noise");
  c.agreement_step_m = number("walk calibration agreement step");
  c.agreement_step_deg = number("walk calibration agreement step");
  c.num_samples = static_cast<int64_t>(parse_unsigned(t[at++], w, "walk calibration samples", 10, INT64_MAX));
  c.num_positive = static_cast<int64_t>(parse_unsigned(t[at++], w, "walk calibration positives", 10, INT64_MAX));
  c.target_precision = number("walk calibration target precision");
  c.check(w + ": walk calibration");
  return c;
}

}  // namespace

BundleIndex read_bundle_index(const std::filesystem::path& path) {
  TextLineReader in(path);
  BundleIndex index;
  const auto expect = [&in](const char* key, size_t count) { return in.expect(key, count); };
  {
    const auto t = expect("lmb-bundle", 1);
    LMB_CHECK(t[0] == "1" || t[0] == "2" || t[0] == "3" || t[0] == "4",
              in.where() << ": format version " << t[0] << " is not supported (this build reads 1 to 4)");
    index.version = t[0][0] - '0';
  }
  // (Each line's tokens are read before in.where() names it: argument order is unspecified.)
  const std::string reach = expect("reach", 1)[0];
  index.reach = parse_finite_number(reach, in.where(), "reach");
  LMB_CHECK(index.reach >= 0.0, in.where() << ": reach " << index.reach << " is negative");
  if (index.version >= 3) {
    const std::string map = expect("map", 1)[0];
    index.map_fingerprint = parse_hex64(map, in.where(), "map");
    LMB_CHECK(index.map_fingerprint != 0, in.where() << ": map fingerprint is zero");
  }
  LMB_CHECK(in.next(), path.string() << ": ends before the 'areas' line");
  constexpr size_t kF = PoseEvidence::kNumFeatures;
  const bool calibrated =
      index.version == 2 || (index.version >= 3 && !in.tokens().empty() && in.tokens().front() == "calibration");
  if (calibrated) {
    const std::vector<std::string> t = in.tokens();
    LMB_CHECK(!t.empty() && t[0] == "calibration" && t.size() == kF + 6,
              in.where() << ": expected 'calibration' and " << kF + 5 << " value(s), found '" << in.line() << "'");
    const std::string w = in.where();
    PoseCalibration c;
    for (size_t k = 0; k < kF; ++k) c.weights[k] = parse_finite_number(t[1 + k], w, "calibration weight");
    c.bias = parse_finite_number(t[kF + 1], w, "calibration bias");
    c.threshold = parse_finite_number(t[kF + 2], w, "calibration threshold");
    c.num_samples = static_cast<int64_t>(parse_unsigned(t[kF + 3], w, "calibration samples", 10, INT64_MAX));
    c.num_positive = static_cast<int64_t>(parse_unsigned(t[kF + 4], w, "calibration positives", 10, INT64_MAX));
    c.target_precision = parse_finite_number(t[kF + 5], w, "calibration target precision");
    c.check(w + ": calibration");
    index.calibration = c;
    LMB_CHECK(in.next(), path.string() << ": ends before the 'areas' line");
    if (index.version >= 4 && !in.tokens().empty() && in.tokens().front() == "walk_calibration") {
      index.walk_calibration = parse_walk_calibration(in.tokens(), in.where(), in.line());
      LMB_CHECK(in.next(), path.string() << ": ends before the 'areas' line");
    }
  }
  const std::vector<std::string> t = in.tokens();
  LMB_CHECK(t.size() == 2 && t[0] == "areas", in.where()
                                                  << ": expected 'areas' and 1 value(s), found '" << in.line() << "'");
  const uint64_t num_areas = parse_unsigned(t[1], in.where(), "areas", 10, 1000000);
  LMB_CHECK(num_areas >= 1, in.where() << ": a bundle needs at least one area");
  const size_t fields = index.version >= 3 ? 22 : 16;
  std::set<std::string> files;
  for (uint64_t i = 0; i < num_areas; ++i) {
    const auto a = expect("area", fields);
    const std::string w = in.where();
    index.areas.push_back(parse_area(a, w, index.version, i, num_areas));
    LMB_CHECK(files.insert(index.areas.back().file).second,
              w << ": file '" << index.areas.back().file << "' is another area's model too");
  }
  LMB_CHECK(!in.next(), in.where() << ": unexpected line after the last area");
  return index;
}

}  // namespace lmb
