#include "train/boost/train_config.h"

#include <fstream>
#include <functional>
#include <map>
#include <sstream>

#include <toml++/toml.h>

#include "common/error.h"

namespace lmb {

namespace {

// One table's keys: name -> setter from a TOML node, getter into a TOML table.
struct Field {
  std::function<void(const toml::node&, const std::string&)> set;
  std::function<void(toml::table&)> get;
};

template <class T>
Field int_field(const std::string& key, T* v) {
  return {[v](const toml::node& n, const std::string& where) {
            // is_integer() first: toml++'s value<int64_t>() of a float node such as 1e37 casts it
            // to int64 before its range check (undefined behaviour, found by fuzz_train_config).
            LMB_CHECK(n.is_integer(), where << ": expected an integer");
            const auto x = n.value<int64_t>();
            LMB_CHECK(x.has_value(), where << ": expected an integer");
            LMB_CHECK(*x >= static_cast<int64_t>(std::numeric_limits<T>::lowest()) &&
                          static_cast<uint64_t>(*x < 0 ? 0 : *x) <= static_cast<uint64_t>(std::numeric_limits<T>::max()),
                      where << ": " << *x << " is out of range");
            *v = static_cast<T>(*x);
          },
          [key, v](toml::table& t) { t.insert_or_assign(key, static_cast<int64_t>(*v)); }};
}
Field double_field(const std::string& key, double* v) {
  return {[v](const toml::node& n, const std::string& where) {
            const auto x = n.value<double>();
            LMB_CHECK(x.has_value() && (n.is_floating_point() || n.is_integer()), where << ": expected a number");
            *v = *x;
          },
          [key, v](toml::table& t) { t.insert_or_assign(key, *v); }};
}
Field bool_field(const std::string& key, bool* v) {
  return {[v](const toml::node& n, const std::string& where) {
            LMB_CHECK(n.is_boolean(), where << ": expected true or false");
            *v = *n.value<bool>();
          },
          [key, v](toml::table& t) { t.insert_or_assign(key, *v); }};
}

using Schema = std::map<std::string, std::map<std::string, Field>>;

Schema schema(TrainConfig* c) {
  Schema s;
  auto& ts = s["training_set"];
  TrainingSetOptions& t = c->training_set;
  ts.emplace("top_k_landmarks", int_field("top_k_landmarks", &t.top_k_landmarks));
  ts.emplace("min_train_observations", int_field("min_train_observations", &t.min_train_observations));
  ts.emplace("validation_fraction", double_field("validation_fraction", &t.validation_fraction));
  ts.emplace("background_cap", int_field("background_cap", &t.background_cap));
  ts.emplace("seed", int_field("seed", &t.seed));
  auto& bs = s["boost"];
  BoostOptions& b = c->boost;
  bs.emplace("num_rounds", int_field("num_rounds", &b.num_rounds));
  bs.emplace("dims_per_round", int_field("dims_per_round", &b.dims_per_round));
  bs.emplace("candidate_dims", int_field("candidate_dims", &b.candidate_dims));
  bs.emplace("max_thresholds_per_dim", int_field("max_thresholds_per_dim", &b.max_thresholds_per_dim));
  bs.emplace("negative_weight_ratio", double_field("negative_weight_ratio", &b.negative_weight_ratio));
  bs.emplace("background_negatives", int_field("background_negatives", &b.background_negatives));
  bs.emplace("learning_rate", double_field("learning_rate", &b.learning_rate));
  bs.emplace("negatives_per_class", int_field("negatives_per_class", &b.negatives_per_class));
  bs.emplace("max_negatives_per_class", int_field("max_negatives_per_class", &b.max_negatives_per_class));
  bs.emplace("mining_interval", int_field("mining_interval", &b.mining_interval));
  bs.emplace("mining_pool_size", int_field("mining_pool_size", &b.mining_pool_size));
  bs.emplace("mined_per_sample", int_field("mined_per_sample", &b.mined_per_sample));
  bs.emplace("exclusion_radius", double_field("exclusion_radius", &b.exclusion_radius));
  bs.emplace("validation_interval", int_field("validation_interval", &b.validation_interval));
  bs.emplace("max_validation_samples", int_field("max_validation_samples", &b.max_validation_samples));
  bs.emplace("sharing_single_starts", int_field("sharing_single_starts", &b.sharing_single_starts));
  bs.emplace("sharing_max_iterations", int_field("sharing_max_iterations", &b.sharing_max_iterations));
  bs.emplace("refine_top", int_field("refine_top", &b.refine_top));
  bs.emplace("screening_step", bool_field("screening_step", &b.screening_step));
  bs.emplace("blocked_screening", bool_field("blocked_screening", &b.blocked_screening));
  bs.emplace("seed", int_field("seed", &b.seed));
  auto& rs = s["regions"];
  ContextRegionOptions& r = c->regions;
  rs.emplace("num_regions", int_field("num_regions", &r.num_regions));
  rs.emplace("seed", int_field("seed", &r.seed));
  rs.emplace("min_area", double_field("min_area", &r.min_area));
  rs.emplace("max_area", double_field("max_area", &r.max_area));
  rs.emplace("max_aspect", double_field("max_aspect", &r.max_aspect));
  rs.emplace("max_offset", double_field("max_offset", &r.max_offset));
  s["features"].emplace("threads", int_field("threads", &c->feature_threads));
  s["checkpoint"].emplace("interval", int_field("interval", &c->checkpoint_interval));
  s["checkpoint"].emplace("keep", int_field("keep", &c->checkpoint_keep));
  return s;
}

}  // namespace

void TrainConfig::check() const {
  training_set.check();
  boost.check();
  regions.check();
  LMB_CHECK(feature_threads >= 1 && feature_threads <= 256,
            "config: features.threads must be in 1..256, got " << feature_threads);
  LMB_CHECK(checkpoint_interval >= 0, "config: checkpoint.interval must be >= 0, got " << checkpoint_interval);
  LMB_CHECK(checkpoint_keep >= 1, "config: checkpoint.keep must be >= 1, got " << checkpoint_keep);
}

void apply_train_config_toml(const std::string& text, const std::string& what, TrainConfig* config) {
  toml::table doc;
  try {
    doc = toml::parse(text, what);
  } catch (const toml::parse_error& e) {
    std::ostringstream os;
    os << e.description() << " at line " << e.source().begin.line;
    LMB_FAIL(what << ": " << os.str());
  }
  Schema s = schema(config);
  for (const auto& [table_key, node] : doc) {
    const std::string table(table_key.str());
    auto it = s.find(table);
    LMB_CHECK(it != s.end(), what << ": unknown table [" << table << "]");
    const toml::table* t = node.as_table();
    LMB_CHECK(t != nullptr, what << ": [" << table << "] must be a table");
    for (const auto& [key_node, value] : *t) {
      const std::string key(key_node.str());
      auto f = it->second.find(key);
      LMB_CHECK(f != it->second.end(), what << ": unknown key " << table << "." << key);
      f->second.set(value, what + ": " + table + "." + key);
    }
  }
}

TrainConfig read_train_config(const std::filesystem::path& path) {
  std::ifstream in(path);
  LMB_CHECK(in.good(), path.string() << ": cannot open the config");
  std::stringstream ss;
  ss << in.rdbuf();
  TrainConfig c;
  apply_train_config_toml(ss.str(), path.string(), &c);
  return c;
}

std::string train_config_toml(const TrainConfig& config) {
  TrainConfig copy = config;
  Schema s = schema(&copy);
  toml::table doc;
  for (auto& [table, fields] : s) {
    toml::table t;
    for (auto& [key, f] : fields) f.get(t);
    doc.insert_or_assign(table, std::move(t));
  }
  std::ostringstream os;
  os << doc << '\n';
  return os.str();
}

}  // namespace lmb
