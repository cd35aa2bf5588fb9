#include "common/text_parse.h"

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

std::string error_of(const std::string& token) {
  try {
    parse_finite_number(token, "f.txt line 3", "X");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ParseFiniteNumber, ParsesWholeTokens) {
  EXPECT_EQ(parse_finite_number("1.5", "", "X"), 1.5);
  EXPECT_EQ(parse_finite_number("-2e3", "", "X"), -2000.0);
  EXPECT_EQ(parse_finite_number("1305031102.175304", "", "X"), 1305031102.175304);
}

TEST(ParseFiniteNumber, RejectsWithPlaceAndReason) {
  EXPECT_EQ(error_of("1x"), "f.txt line 3: X is not a number: '1x'");
  EXPECT_EQ(error_of(""), "f.txt line 3: X is not a number: ''");
  EXPECT_EQ(error_of("abc"), "f.txt line 3: X is not a number: 'abc'");
  EXPECT_EQ(error_of("nan"), "f.txt line 3: X is not finite");
  EXPECT_EQ(error_of("-inf"), "f.txt line 3: X is not finite");
  EXPECT_EQ(error_of("1e400"), "f.txt line 3: X is not finite");
}

}  // namespace
}  // namespace lmb
