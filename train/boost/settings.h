// Settings schemas: each setting of an options struct is named once, with where its value lives,
// the values it accepts and a line of help. A schema drives reading (train/boost/train_config.h:
// TOML in), writing (TOML out), validation (check_settings) and the defaults the command line
// prints (describe_setting).
#pragma once

#include <cstdint>
#include <limits>
#include <sstream>
#include <string>
#include <variant>
#include <vector>

#include "common/error.h"

namespace lmb {

// Where a setting's value lives.
using SettingRef = std::variant<int32_t*, int64_t*, uint64_t*, double*, bool*>;

// The values a numeric setting accepts: an interval, each end closed or open (an open infinite
// end also excludes infinity). NaN is never inside. Integers are further bounded by their type.
struct SettingRange {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false, hi_open = false;

  static SettingRange any() { return {}; }
  static SettingRange at_least(double lo) { return {lo, std::numeric_limits<double>::infinity(), false, false}; }
  static SettingRange finite_at_least(double lo) { return {lo, std::numeric_limits<double>::infinity(), false, true}; }
  static SettingRange closed(double lo, double hi) { return {lo, hi, false, false}; }
  static SettingRange half_open(double lo, double hi) { return {lo, hi, false, true}; }    // [lo, hi)
  static SettingRange open_closed(double lo, double hi) { return {lo, hi, true, false}; }  // (lo, hi]

  bool contains(double v) const {
    const bool above = lo_open ? v > lo : v >= lo;
    const bool below = hi_open ? v < hi : v <= hi;
    return above && below;
  }
  bool unbounded() const {
    return lo == -std::numeric_limits<double>::infinity() && hi == std::numeric_limits<double>::infinity() &&
           !lo_open && !hi_open;
  }
  // "in [0, 255]", ">= 1", "in (0, 1]", "finite and >= 0".
  std::string text() const {
    std::ostringstream os;
    const bool lo_inf = lo == -std::numeric_limits<double>::infinity();
    const bool hi_inf = hi == std::numeric_limits<double>::infinity();
    if (!lo_inf && hi_inf) {
      os << (hi_open ? "finite and " : "") << (lo_open ? "> " : ">= ") << lo;
    } else if (lo_inf && !hi_inf) {
      os << (hi_open ? "< " : "<= ") << hi;
    } else {
      os << "in " << (lo_open ? '(' : '[') << lo << ", " << hi << (hi_open ? ')' : ']');
    }
    return os.str();
  }
};

template <class T>
struct Setting {
  const char* key;               // the name in the config file
  SettingRef (*ref)(T& object);  // the value inside an object
  SettingRange range;
  const char* help;
};

// The value as the config file spells it (integers as integers, bools as true / false).
inline std::string setting_value_text(const SettingRef& ref) {
  std::ostringstream os;
  std::visit(
      [&](auto* v) {
        if constexpr (std::is_same_v<std::remove_pointer_t<decltype(v)>, bool>) {
          os << (*v ? "true" : "false");
        } else {
          os << *v;
        }
      },
      ref);
  return os.str();
}

// The value as a double (range checks); bools are 0 / 1.
inline double setting_as_double(const SettingRef& ref) {
  return std::visit([](auto* v) { return static_cast<double>(*v); }, ref);
}

// Throws lmb::Error "<what>: <key> must be <range>, got <value>" for the first value out of range.
template <class T>
void check_settings(const char* what, const std::vector<Setting<T>>& settings, const T& object) {
  T copy = object;
  for (const Setting<T>& s : settings) {
    if (s.range.unbounded()) continue;
    const SettingRef ref = s.ref(copy);
    LMB_CHECK(s.range.contains(setting_as_double(ref)),
              what << ": " << s.key << " must be " << s.range.text() << ", got " << setting_value_text(ref));
  }
}

// "<help> (default <value>)", the default read from a default-constructed T.
template <class T>
std::string describe_setting(const Setting<T>& s) {
  T defaults{};
  return std::string(s.help) + " (default " + setting_value_text(s.ref(defaults)) + ")";
}

}  // namespace lmb
