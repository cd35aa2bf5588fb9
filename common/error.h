// Error handling: every check on user input throws lmb::Error with a message that says what and
// where. Hot loops use assert only.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace lmb {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

namespace detail {
[[noreturn]] void throw_error(const char* file, int line, const std::string& message);
}  // namespace detail

}  // namespace lmb

// LMB_CHECK(cond, "stream" << "able" << message): throws lmb::Error with the message when cond is
// false. The message is what the user reads, so name the file, field and reason.
#define LMB_CHECK(cond, msg)                                                   \
  do {                                                                         \
    if (!(cond)) {                                                             \
      std::ostringstream lmb_check_stream_;                                    \
      lmb_check_stream_ << msg;                                                \
      ::lmb::detail::throw_error(__FILE__, __LINE__, lmb_check_stream_.str()); \
    }                                                                          \
  } while (false)

#define LMB_FAIL(msg) LMB_CHECK(false, msg)
