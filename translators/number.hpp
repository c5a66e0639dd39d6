// Number text <-> double, without locale and without allocation (the hot path of every line).
#pragma once
#include <string>
#include <string_view>

namespace xlate5 {

// Appends v with at most `decimals` digits after the point, trailing zeros and a bare point
// removed, and "-0" written as "0" (what firmware parsers and diff tools expect).
void append_fixed(std::string& out, double v, int decimals);

// Appends the shortest text that reads back as exactly v (for values passed through, such as E).
void append_shortest(std::string& out, double v);

// Rounds v to `decimals` places the way append_fixed prints it.
double round_to(double v, int decimals);

}  // namespace xlate5
