#include "common/text_parse.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>

#include "common/error.h"

namespace lmb {

double parse_finite_number(const std::string& token, const std::string& where, const std::string& field) {
  const char* begin = token.c_str();
  char* end = nullptr;
  errno = 0;
  const double value = token.empty() ? 0.0 : std::strtod(begin, &end);
  LMB_CHECK(!token.empty() && end == begin + token.size(),
            where << ": " << field << " is not a number: '" << token << "'");
  LMB_CHECK(std::isfinite(value) && errno != ERANGE, where << ": " << field << " is not finite");
  return value;
}

double parse_number_or_infinity(const std::string& token, const std::string& where, const std::string& field) {
  if (token == "inf") return std::numeric_limits<double>::infinity();
  if (token == "-inf") return -std::numeric_limits<double>::infinity();
  return parse_finite_number(token, where, field);
}

std::string exact_number_text(double v) {
  if (std::isinf(v)) return v < 0 ? "-inf" : "inf";
  if (v == 0.0) v = 0.0;  // no "-0"
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

}  // namespace lmb
