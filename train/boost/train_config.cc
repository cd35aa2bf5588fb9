#include "train/boost/train_config.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <optional>
#include <sstream>
#include <type_traits>
#include <utility>

#include <toml++/toml.h>

#include "common/error.h"
#include "common/file_io.h"

namespace lmb {

namespace {

const std::vector<Setting<ContextRegionOptions>>& region_settings() {
  using T = ContextRegionOptions;
  // Ranges: ContextRegionOptions::check (common/context_regions.h), shared with the inference model.
  static const std::vector<Setting<T>> settings = {
      {"num_regions", [](T& o) -> SettingRef { return &o.num_regions; }, SettingRange::any(), "R, context regions"},
      {"seed", [](T& o) -> SettingRef { return &o.seed; }, SettingRange::any(), "seed of the random regions"},
      {"min_area", [](T& o) -> SettingRef { return &o.min_area; }, SettingRange::any(),
       "smallest region area, squared keypoint scales"},
      {"max_area", [](T& o) -> SettingRef { return &o.max_area; }, SettingRange::any(),
       "largest region area, squared keypoint scales"},
      {"max_aspect", [](T& o) -> SettingRef { return &o.max_aspect; }, SettingRange::any(),
       "largest width / height (and height / width)"},
      {"max_offset", [](T& o) -> SettingRef { return &o.max_offset; }, SettingRange::any(),
       "largest centre distance from the keypoint, keypoint scales"},
  };
  return settings;
}

const std::vector<Setting<TrainConfig>>& feature_settings() {
  using T = TrainConfig;
  static const std::vector<Setting<T>> settings = {
      {"threads", [](T& c) -> SettingRef { return &c.feature_threads; }, SettingRange::closed(1, 256),
       "threads of the feature building"},
  };
  return settings;
}

const std::vector<Setting<TrainConfig>>& checkpoint_settings() {
  using T = TrainConfig;
  static const std::vector<Setting<T>> settings = {
      {"minutes", [](T& c) -> SettingRef { return &c.checkpoint_minutes; }, SettingRange::finite_at_least(0),
       "wall minutes between checkpoints (0 = none by time); checkpoints also come on SIGTERM / SIGUSR1 and at "
       "the end"},
      {"interval", [](T& c) -> SettingRef { return &c.checkpoint_interval; }, SettingRange::at_least(0),
       "rounds between checkpoints (0 = none by rounds), besides checkpoint.minutes"},
      {"keep", [](T& c) -> SettingRef { return &c.checkpoint_keep; }, SettingRange::at_least(1),
       "newest checkpoints kept"},
  };
  return settings;
}

// The keys of one table: `settings` of the part of a TrainConfig that `part` returns.
template <class Part>
void add_table(std::vector<ConfigKey>* schema, const char* table, Part& (*part)(TrainConfig&),
               const std::vector<Setting<Part>>& settings) {
  for (const Setting<Part>& s : settings) {
    schema->push_back(
        {table, s.key, [part, ref = s.ref](TrainConfig& c) { return ref(part(c)); }, s.range, describe_setting(s)});
  }
}

// A TOML node into the value a key refers to; `where` names the file and key.
void set_value(const toml::node& n, const std::string& where, const SettingRef& ref) {
  std::visit(
      [&](auto* v) {
        using T = std::remove_pointer_t<decltype(v)>;
        if constexpr (std::is_same_v<T, bool>) {
          LMB_CHECK(n.is_boolean(), where << ": expected true or false");
          *v = *n.value<bool>();
        } else if constexpr (std::is_floating_point_v<T>) {
          const auto x = n.value<double>();
          LMB_CHECK(x.has_value() && (n.is_floating_point() || n.is_integer()), where << ": expected a number");
          *v = *x;
        } else {
          // is_integer() first: toml++'s value<int64_t>() of a float node such as 1e37 casts it
          // to int64 before its range check (undefined behaviour, found by fuzz_train_config).
          LMB_CHECK(n.is_integer(), where << ": expected an integer");
          const auto x = n.value<int64_t>();
          LMB_CHECK(x.has_value(), where << ": expected an integer");
          LMB_CHECK(*x >= static_cast<int64_t>(std::numeric_limits<T>::lowest()) &&
                        static_cast<uint64_t>(*x < 0 ? 0 : *x) <= static_cast<uint64_t>(std::numeric_limits<T>::max()),
                    where << ": " << *x << " is out of range");
          *v = static_cast<T>(*x);
        }
      },
      ref);
}

// The value a key refers to, into a TOML table (integers as int64).
void put_value(toml::table& t, const std::string& key, const SettingRef& ref) {
  std::visit(
      [&](auto* v) {
        using T = std::remove_pointer_t<decltype(v)>;
        if constexpr (std::is_same_v<T, bool> || std::is_floating_point_v<T>) {
          t.insert_or_assign(key, *v);
        } else {
          t.insert_or_assign(key, static_cast<int64_t>(*v));
        }
      },
      ref);
}

// The [area] table into `area`: every key required, no other key.
void apply_area_table(const toml::node& node, const std::string& what, AreaReference* area) {
  const toml::table* t = node.as_table();
  LMB_CHECK(t != nullptr, what << ": [area] must be a table");
  AreaReference a;
  bool has_file = false, has_id = false, has_landmarks = false, has_hash = false;
  for (const auto& [key_node, value] : *t) {
    const std::string key(key_node.str());
    const std::string where = what + ": area." + key;
    if (key == "file") {
      LMB_CHECK(value.is_string() && !value.value<std::string>()->empty(), where << ": expected a non-empty string");
      a.file = *value.value<std::string>();
      has_file = true;
    } else if (key == "id" || key == "landmarks") {
      LMB_CHECK(value.is_integer(), where << ": expected an integer");
      const int64_t v = *value.value<int64_t>();
      if (key == "id") {
        LMB_CHECK(v >= 0 && v <= std::numeric_limits<int32_t>::max(), where << ": " << v << " is out of range");
        a.id = static_cast<int32_t>(v);
        has_id = true;
      } else {
        LMB_CHECK(v >= 1, where << ": " << v << " must be >= 1");
        a.landmarks = v;
        has_landmarks = true;
      }
    } else if (key == "landmarks_hash") {
      const std::optional<std::string> text = value.value<std::string>();
      char* end = nullptr;
      LMB_CHECK(value.is_string() && text->size() == 16, where << ": expected 16 hex digits");
      a.landmarks_hash = std::strtoull(text->c_str(), &end, 16);
      LMB_CHECK(end == text->c_str() + 16, where << ": expected 16 hex digits");
      has_hash = true;
    } else {
      LMB_FAIL(what << ": unknown key area." << key);
    }
  }
  LMB_CHECK(has_file && has_id && has_landmarks && has_hash,
            what << ": [area] needs file, id, landmarks and landmarks_hash");
  *area = a;
}

}  // namespace

const std::vector<ConfigKey>& train_config_schema() {
  static const std::vector<ConfigKey> schema = [] {
    std::vector<ConfigKey> s;
    add_table<TrainingSetOptions>(
        &s, "training_set", [](TrainConfig& c) -> TrainingSetOptions& { return c.training_set; },
        training_set_settings());
    add_table<BoostOptions>(
        &s, "boost", [](TrainConfig& c) -> BoostOptions& { return c.boost; }, boost_settings());
    add_table<ContextRegionOptions>(
        &s, "regions", [](TrainConfig& c) -> ContextRegionOptions& { return c.regions; }, region_settings());
    add_table<AugmentOptions>(
        &s, "augment", [](TrainConfig& c) -> AugmentOptions& { return c.augment; }, augment_settings());
    add_table<TrainConfig>(
        &s, "features", [](TrainConfig& c) -> TrainConfig& { return c; }, feature_settings());
    add_table<TrainConfig>(
        &s, "checkpoint", [](TrainConfig& c) -> TrainConfig& { return c; }, checkpoint_settings());
    return s;
  }();
  return schema;
}

std::string describe_config_key(const std::string& name) {
  for (const ConfigKey& k : train_config_schema()) {
    if (k.name() == name) return k.help;
  }
  LMB_FAIL("config: no key " << name);
}

void TrainConfig::check() const {
  training_set.check();
  boost.check();
  regions.check();
  augment.check();
  TrainConfig copy = *this;
  for (const ConfigKey& k : train_config_schema()) {
    if (k.table != "features" && k.table != "checkpoint") continue;  // the others: their check()
    const SettingRef ref = k.ref(copy);
    LMB_CHECK(k.range.contains(setting_as_double(ref)),
              "config: " << k.name() << " must be " << k.range.text() << ", got " << setting_value_text(ref));
  }
  if (area.set()) {
    LMB_CHECK(area.id >= 0, "config: area.id must be >= 0, got " << area.id);
    LMB_CHECK(area.landmarks >= 1, "config: area.landmarks must be >= 1, got " << area.landmarks);
  }
  // Seeds are written to config.toml as TOML integers (int64).
  constexpr uint64_t kMaxSeed = static_cast<uint64_t>(std::numeric_limits<int64_t>::max());
  for (const auto& [name, seed] :
       {std::pair{"training_set.seed", training_set.seed}, std::pair{"boost.seed", boost.seed},
        std::pair{"regions.seed", regions.seed}, std::pair{"augment.seed", augment.seed}}) {
    LMB_CHECK(seed <= kMaxSeed, "config: " << name << " = " << seed << " must be in 0.." << kMaxSeed);
  }
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
  const std::vector<ConfigKey>& schema = train_config_schema();
  for (const auto& [table_key, node] : doc) {
    const std::string table(table_key.str());
    if (table == "area") {
      apply_area_table(node, what, &config->area);
      continue;
    }
    LMB_CHECK(std::any_of(schema.begin(), schema.end(), [&](const ConfigKey& k) { return k.table == table; }),
              what << ": unknown table [" << table << "]");
    const toml::table* t = node.as_table();
    LMB_CHECK(t != nullptr, what << ": [" << table << "] must be a table");
    for (const auto& [key_node, value] : *t) {
      const std::string key(key_node.str());
      const auto k = std::find_if(schema.begin(), schema.end(),
                                  [&](const ConfigKey& c) { return c.table == table && c.key == key; });
      LMB_CHECK(k != schema.end(), what << ": unknown key " << table << "." << key);
      set_value(value, what + ": " + table + "." + key, k->ref(*config));
    }
  }
}

TrainConfig read_train_config(const std::filesystem::path& path) {
  TrainConfig c;
  apply_train_config_toml(read_file(path, 1 << 20), path.string(), &c);
  try {
    c.check();
  } catch (const Error& e) {
    LMB_FAIL(path.string() << ": " << e.what());
  }
  return c;
}

TrainConfig read_run_train_config(const std::filesystem::path& path) {
  const std::string text = read_file(path, 1 << 20);
  TrainConfig c;
  apply_train_config_toml(text, path.string(), &c);
  const toml::table doc = toml::parse(text, path.string());  // parsed above without an error
  if (!doc["training_set"]["calibration_frames"]) c.training_set.calibration_frames = 0;
  if (!doc["training_set"]["calibration_folds"]) c.training_set.calibration_folds = 0;
  try {
    c.check();
  } catch (const Error& e) {
    LMB_FAIL(path.string() << ": " << e.what());
  }
  return c;
}

std::string train_config_toml(const TrainConfig& config) {
  TrainConfig copy = config;
  std::vector<const ConfigKey*> keys;
  for (const ConfigKey& k : train_config_schema()) {
    if (k.table == "augment" && !config.augment.enabled()) continue;
    keys.push_back(&k);
  }
  // By table, then key: the order of the file does not depend on the schema's.
  std::sort(keys.begin(), keys.end(), [](const ConfigKey* a, const ConfigKey* b) {
    return a->table != b->table ? a->table < b->table : a->key < b->key;
  });
  toml::table doc;
  for (size_t i = 0; i < keys.size();) {
    toml::table t;
    size_t j = i;
    for (; j < keys.size() && keys[j]->table == keys[i]->table; ++j) put_value(t, keys[j]->key, keys[j]->ref(copy));
    doc.insert_or_assign(keys[i]->table, std::move(t));
    i = j;
  }
  if (config.area.set()) {
    char hash[24];
    std::snprintf(hash, sizeof(hash), "%016llx", static_cast<unsigned long long>(config.area.landmarks_hash));
    toml::table t;
    t.insert_or_assign("file", config.area.file);
    t.insert_or_assign("id", static_cast<int64_t>(config.area.id));
    t.insert_or_assign("landmarks", config.area.landmarks);
    t.insert_or_assign("landmarks_hash", std::string(hash));
    doc.insert_or_assign("area", std::move(t));
  }
  std::ostringstream os;
  os << doc << '\n';
  return os.str();
}

}  // namespace lmb
