#include "train/checkpoint/checkpoint_h5.h"

#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <map>
#include <sstream>
#include <system_error>

#include <toml++/toml.h>

#include "common/error.h"
#include "common/file_container.h"
#include "common/file_io.h"
#include "common/io/h5_util.h"
#include "train/boost/boost_model.h"

namespace lmb {

namespace fs = std::filesystem;
using namespace h5;

namespace {

template <typename T>
uint32_t crc_of(const std::vector<T>& v, uint32_t crc) {
  return crc32(reinterpret_cast<const uint8_t*>(v.data()), v.size() * sizeof(T), crc);
}

std::vector<uint8_t> bytes_of(const std::string& s) { return std::vector<uint8_t>(s.begin(), s.end()); }
std::string string_of(const std::vector<uint8_t>& v) { return std::string(v.begin(), v.end()); }

// The compared settings of a config, "table.key" -> value text.
std::map<std::string, std::string> compared_settings(const std::string& text, const std::string& what) {
  toml::table doc;
  try {
    doc = toml::parse(text, what);
  } catch (const toml::parse_error& e) {
    LMB_FAIL(what << ": " << e.description());
  }
  std::map<std::string, std::string> out;
  for (const auto& [table_key, node] : doc) {
    const std::string table(table_key.str());
    if (table == "checkpoint") continue;
    const toml::table* t = node.as_table();
    if (!t) continue;
    for (const auto& [key_node, value] : *t) {
      const std::string name = table + "." + std::string(key_node.str());
      if (name == "boost.num_rounds" || name == "features.threads") continue;
      std::ostringstream os;
      value.visit([&](const auto& v) { os << v; });
      out[name] = os.str();
    }
  }
  return out;
}

}  // namespace

uint64_t config_hash(const std::string& config_toml) {
  uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a over "name=value\n" of the compared settings
  for (const auto& [k, v] : compared_settings(config_toml, "config")) {
    for (char ch : k + "=" + v + "\n") h = (h ^ static_cast<uint8_t>(ch)) * 0x100000001b3ull;
  }
  return h;
}

std::string config_difference(const std::string& checkpoint_toml, const std::string& current_toml) {
  const auto a = compared_settings(checkpoint_toml, "checkpoint config");
  const auto b = compared_settings(current_toml, "current config");
  for (const auto& [k, v] : a) {
    const auto it = b.find(k);
    if (it == b.end()) return k + " (checkpoint " + v + ", now absent)";
    if (it->second != v) return k + " (checkpoint " + v + ", now " + it->second + ")";
  }
  for (const auto& [k, v] : b) {
    if (!a.count(k)) return k + " (absent in the checkpoint, now " + v + ")";
  }
  return "";
}

void write_checkpoint(const fs::path& path, const Checkpoint& ck) {
  const LearnerState& st = ck.state;
  LMB_CHECK(ck.feature_space.num_dims == st.model.num_dims, path.string() << ": the model has " << st.model.num_dims
                                                                          << " feature dims, its feature space "
                                                                          << ck.feature_space.num_dims);
  H5::Exception::dontPrint();
  try {
    // Built in memory, written by the atomic writer (common/io/h5_util.h).
    write_h5_atomically(path, [&](H5::H5File& file) {
      write_string_attribute(file, "format", kCheckpointFormat);
      write_int_attribute(file, "format_version", kCheckpointVersion);
      write_scalar_attribute<int64_t>(file, "rounds", ck.rounds);
      write_scalar_attribute<int64_t>(file, "seed", static_cast<int64_t>(ck.seed));
      write_scalar_attribute<int64_t>(file, "ranks", ck.ranks);
      std::ostringstream hash;
      hash << std::hex << config_hash(ck.config);
      write_string_attribute(file, "config_hash", hash.str());
      write_string_attribute(file, "data", ck.data);

      uint32_t crc = 0;
      H5::Group root = file.openGroup("/");
      auto put = [&](H5::Group& g, const char* name, const auto& v) {
        write_column(g, name, v, v.size());
        crc = crc_of(v, crc);
      };
      put(root, "config", bytes_of(ck.config));
      put(root, "data_source", bytes_of(ck.data));
      const std::string model = serialize_boost_model(st.model);
      put(root, "model", bytes_of(model));
      put(root, "feature_space", bytes_of(serialize_feature_space(ck.feature_space)));
      H5::Group learner = create_untimed_group(file, "/learner");
      write_scalar_attribute<int64_t>(learner, "weight_exponent", st.weight_exponent);
      write_scalar_attribute<int64_t>(learner, "num_validation_rows", st.num_validation_rows);
      put(learner, "entry_sample", st.entry_sample);
      put(learner, "entry_code", st.entry_code);
      put(learner, "entry_weight", st.entry_weight);
      put(learner, "tracked_samples", st.tracked_samples);
      put(learner, "tracked_scores", st.tracked_scores);
      put(learner, "class_offset", st.class_offset);
      put(learner, "negative_unit", st.negative_unit);
      put(learner, "last_validation", std::vector<double>{st.last_validation});
      write_scalar_attribute<int64_t>(file, "crc32", crc);
      write_int_attribute(file, "complete", 1);
    });
  } catch (const H5::Exception& e) {
    LMB_FAIL(path.string() << ": cannot write the checkpoint: " << e.getDetailMsg());
  } catch (const Error& e) {
    // AtomicFile's "<path>: <step> failed: <reason>" (a full disk, a read-only folder).
    std::string reason = e.what();
    if (reason.rfind(path.string() + ": ", 0) == 0) reason.erase(0, path.string().size() + 2);
    LMB_FAIL(path.string() << ": cannot write the checkpoint: " << reason);
  }
}

Checkpoint read_checkpoint(const fs::path& path) {
  H5::Exception::dontPrint();
  const std::string name = path.string();
  LMB_CHECK(fs::is_regular_file(path), name << ": no such checkpoint file");
  try {
    LMB_CHECK(H5::H5File::isHdf5(name), name << ": not an HDF5 file (torn or corrupt checkpoint)");
    H5::H5File file(name, H5F_ACC_RDONLY);
    Reader r(path, file);
    LMB_CHECK(r.string_attribute("format") == kCheckpointFormat,
              name << ": attribute 'format': not a " << kCheckpointFormat);
    const int64_t version = r.int_attribute("format_version");
    if (version == 1) {
      throw CheckpointVersionError(
          name +
          ": written by an older lboost (checkpoint format version 1), which does not record the "
          "context regions, vocabulary and map it was trained with; finish the run with the lboost that "
          "started it, or train into a new --out folder");
    }
    if (version != kCheckpointVersion) {
      throw CheckpointVersionError(name + ": attribute 'format_version': " + std::to_string(version) +
                                   ", this build reads " + std::to_string(kCheckpointVersion));
    }
    LMB_CHECK(file.attrExists("complete") && r.int_attribute("complete") == 1,
              name << ": attribute 'complete': missing (the write did not finish)");
    Checkpoint ck;
    ck.rounds = static_cast<int32_t>(r.int_attribute("rounds"));
    ck.seed = static_cast<uint64_t>(r.int_attribute("seed"));
    ck.ranks = static_cast<int32_t>(r.int_attribute("ranks"));
    uint32_t crc = 0;
    auto get = [&]<typename T>(const std::string& dataset, std::vector<T>* out) {
      *out = r.column<T>(dataset, -1);
      crc = crc_of(*out, crc);
    };
    std::vector<uint8_t> bytes;
    get("/config", &bytes);
    ck.config = string_of(bytes);
    get("/data_source", &bytes);
    ck.data = string_of(bytes);
    get("/model", &bytes);
    std::vector<uint8_t> space_bytes;
    get("/feature_space", &space_bytes);
    LearnerState& st = ck.state;
    std::vector<double> last;
    get("/learner/entry_sample", &st.entry_sample);
    get("/learner/entry_code", &st.entry_code);
    get("/learner/entry_weight", &st.entry_weight);
    get("/learner/tracked_samples", &st.tracked_samples);
    get("/learner/tracked_scores", &st.tracked_scores);
    get("/learner/class_offset", &st.class_offset);
    get("/learner/negative_unit", &st.negative_unit);
    get("/learner/last_validation", &last);
    const uint32_t stored_crc = static_cast<uint32_t>(r.int_attribute("crc32"));
    LMB_CHECK(crc == stored_crc, name << ": CRC-32 mismatch (stored " << std::hex << stored_crc << ", computed " << crc
                                      << "): corrupt checkpoint");
    LMB_CHECK(last.size() == 1, name << ": dataset '/learner/last_validation': expected 1 value");
    st.last_validation = last[0];
    st.model = deserialize_boost_model(string_of(bytes), name + ": /model");
    ck.feature_space = parse_feature_space(string_of(space_bytes), name + ": /feature_space");
    LMB_CHECK(ck.feature_space.num_dims == st.model.num_dims,
              name << ": /feature_space has " << ck.feature_space.num_dims << " dims, /model " << st.model.num_dims);
    H5::Group learner = file.openGroup("/learner");
    auto group_int = [&](const char* attr) {
      LMB_CHECK(learner.attrExists(attr), name << ": attribute '/learner/" << attr << "': missing");
      int64_t v = 0;
      learner.openAttribute(attr).read(H5::PredType::NATIVE_INT64, &v);
      return v;
    };
    st.weight_exponent = static_cast<int32_t>(group_int("weight_exponent"));
    st.num_validation_rows = group_int("num_validation_rows");
    LMB_CHECK(static_cast<int64_t>(st.model.stumps.size()) == ck.rounds,
              name << ": /model has " << st.model.stumps.size() << " stumps for " << ck.rounds << " rounds");
    return ck;
  } catch (const H5::Exception& e) {
    LMB_FAIL(name << ": torn or corrupt checkpoint: " << e.getDetailMsg());
  }
}

CheckpointDir::CheckpointDir(const fs::path& run_dir) : folder_(run_dir / "checkpoints") {}

fs::path CheckpointDir::path_for(int32_t rounds) const {
  char name[32];
  std::snprintf(name, sizeof(name), "ckpt-%07d.h5", rounds);
  return folder_ / name;
}

std::vector<fs::path> CheckpointDir::list() const {
  std::vector<std::pair<int64_t, fs::path>> found;
  std::error_code ec;
  if (!fs::is_directory(folder_, ec)) return {};
  for (const auto& entry : fs::directory_iterator(folder_)) {
    const std::string n = entry.path().filename().string();
    if (n.size() != 15 || n.rfind("ckpt-", 0) != 0 || n.substr(12) != ".h5") continue;
    const std::string digits = n.substr(5, 7);
    if (!std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) continue;
    found.emplace_back(std::stoll(digits), entry.path());
  }
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<fs::path> out;
  for (auto& f : found) out.push_back(std::move(f.second));
  return out;
}

std::optional<Checkpoint> CheckpointDir::newest_valid(
    const std::function<void(const fs::path&, const std::string&)>& on_skip) const {
  for (const fs::path& p : list()) {
    try {
      return read_checkpoint(p);
    } catch (const CheckpointVersionError&) {
      throw;
    } catch (const Error& e) {
      if (on_skip) on_skip(p, e.what());
    }
  }
  return std::nullopt;
}

fs::path CheckpointDir::write(const Checkpoint& checkpoint, int keep) const {
  LMB_CHECK(keep >= 1, "checkpoint.keep must be at least 1, got " << keep);
  std::error_code ec;
  fs::create_directories(folder_, ec);
  LMB_CHECK(!ec, folder_.string() << ": cannot create the checkpoint folder: " << ec.message());
  // ".ckpt-NNNNNNN.h5.tmp-PID" of a writer killed while it wrote: up to a whole checkpoint each.
  remove_stale_temporaries(folder_);
  const fs::path path = path_for(checkpoint.rounds);
  write_checkpoint(path, checkpoint);
  const auto all = list();
  for (size_t i = static_cast<size_t>(keep); i < all.size(); ++i) fs::remove(all[i], ec);
  return path;
}

}  // namespace lmb
