// The one reader of the project's binary payloads (model.lbm, model.bin, vocabulary, checkpoints'
// model): a cereal portable binary archive over bytes in memory that checks every count against the
// bytes left before anything is allocated from it (cereal itself trusts size fields, so a corrupt
// count would otherwise ask for terabytes).
//
// Errors are lmb::Error "<what>: <field>: corrupt count N exceeds the M bytes left". A read past
// the end throws cereal::Exception; callers turn it into "<what>: truncated or corrupt ...".
#pragma once

#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include <cereal/archives/portable_binary.hpp>

#include "common/error.h"

namespace lmb {

class BoundedReader {
 public:
  // `what` names the source (a path) in errors.
  BoundedReader(const std::string& bytes, std::string what)
      : is_(bytes), ar_(is_), total_(bytes.size()), what_(std::move(what)) {}

  const std::string& what() const { return what_; }

  // One arithmetic value.
  template <class T>
  void value(T& x) {
    ar_(x);
  }
  template <class T>
  T value() {
    T x{};
    ar_(x);
    return x;
  }

  uint64_t bytes_left() {
    const auto pos = is_.tellg();
    LMB_CHECK(pos >= 0, what_ << ": truncated payload");
    return total_ - static_cast<uint64_t>(pos);
  }

  // A uint64 count of elements that take at least `min_element_bytes` bytes each, checked against
  // the bytes left.
  uint64_t count(uint64_t min_element_bytes, const char* field) {
    uint64_t n = 0;
    ar_(n);
    const uint64_t left = bytes_left();
    LMB_CHECK(n <= left / min_element_bytes,
              what_ << ": " << field << ": corrupt count " << n << " exceeds the " << left << " bytes left");
    return n;
  }

  // A vector of arithmetic values stored as a uint64 count and the values.
  template <class T>
  void vector(std::vector<T>& v, const char* field) {
    v.resize(count(sizeof(T), field));
    for (T& x : v) ar_(x);
  }

  // A byte string stored as a uint64 size and the bytes.
  std::string byte_string(const char* field, uint64_t max_size = UINT64_MAX) {
    const uint64_t n = count(1, field);
    LMB_CHECK(n <= max_size, what_ << ": " << field << ": " << n << " bytes exceed " << max_size);
    std::string s(n, '\0');
    if (n > 0) ar_(cereal::binary_data(s.data(), n));
    return s;
  }

  // Throws unless every byte was read.
  void expect_end() {
    const uint64_t left = bytes_left();
    LMB_CHECK(left == 0, what_ << ": " << left << " unexpected bytes after the end");
  }

 private:
  std::istringstream is_;
  cereal::PortableBinaryInputArchive ar_;
  uint64_t total_;
  std::string what_;
};

// The writing side of a byte string (uint64 size + bytes), as BoundedReader::byte_string reads it.
inline void write_byte_string(cereal::PortableBinaryOutputArchive& ar, const std::string& s) {
  ar(static_cast<uint64_t>(s.size()));
  if (!s.empty()) ar(cereal::binary_data(s.data(), s.size()));
}

}  // namespace lmb
