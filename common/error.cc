#include "common/error.h"

namespace lmb::detail {

void throw_error(const char* /*file*/, int /*line*/, const std::string& message) {
  // The message is for users: it names the input and the reason. Source locations stay out of it;
  // a debugger or LMB_CHECK's call site finds them.
  throw Error(message);
}

}  // namespace lmb::detail
