// Number text <-> double, without locale and without allocation (the hot path of every line).
// No stage: the lexer and the emitters call it. Calls nothing.
#pragma once
#include <string>
#include <string_view>

namespace xlate5 {

// Appends v with at most `decimals` digits after the point, trailing zeros and a bare point
// removed, and "-0" written as "0" (what firmware parsers and diff tools expect).
void append_fixed(std::string& out, double v, int decimals);

// Appends the shortest text that reads back as exactly v (for values passed through, such as E).
void append_shortest(std::string& out, double v);

// v in units of 10^-decimals, rounded half away from zero: what append_fixed prints. False if
// out of the fast range (then append_fixed falls back to std::to_chars).
bool to_units(double v, int decimals, long long& units);
// Appends units * 10^-decimals with trailing fraction zeros removed.
void append_units(std::string& out, long long units, int decimals);

}  // namespace xlate5
