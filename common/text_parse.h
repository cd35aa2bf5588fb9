// Parsing numbers out of text files with errors that name the place.
#pragma once

#include <string>

namespace lmb {

// Parses a whole token as a finite double. Throws lmb::Error "<where>: <field> is not a number:
// '<token>'" for an empty token, trailing characters or an unparsable one, and "<where>: <field>
// is not finite" for NaN, infinity or overflow.
double parse_finite_number(const std::string& token, const std::string& where, const std::string& field);

// A whole token as a double that may be "inf" or "-inf" (an unbounded end), never NaN; otherwise
// as parse_finite_number.
double parse_number_or_infinity(const std::string& token, const std::string& where, const std::string& field);

// The text of v that parses back to the same double ("%.17g"; "inf" / "-inf"; no "-0").
std::string exact_number_text(double v);

}  // namespace lmb
