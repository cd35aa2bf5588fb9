#include "common/text_parse.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "common/error.h"

namespace lmb {

double parse_finite_number(const std::string& token, const std::string& where,
                           const std::string& field) {
  const char* begin = token.c_str();
  char* end = nullptr;
  errno = 0;
  const double value = token.empty() ? 0.0 : std::strtod(begin, &end);
  LMB_CHECK(!token.empty() && end == begin + token.size(),
            where << ": " << field << " is not a number: '" << token << "'");
  LMB_CHECK(std::isfinite(value) && errno != ERANGE, where << ": " << field << " is not finite");
  return value;
}

}  // namespace lmb
