#include "translators/number.hpp"

#include <charconv>
#include <cmath>

namespace xlate5 {

namespace {
void trim_zeros(std::string& out, std::size_t start) {
    auto dot = out.find('.', start);
    if (dot == std::string::npos) return;
    auto end = out.size();
    while (end > dot + 1 && out[end - 1] == '0') --end;
    if (end == dot + 1) --end;
    out.resize(end);
    if (out.size() == start + 2 && out[start] == '-' && out[start + 1] == '0') out.erase(start, 1);
}
}  // namespace

void append_fixed(std::string& out, double v, int decimals) {
    char buf[64];
    auto res = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
    auto start = out.size();
    out.append(buf, res.ptr);
    trim_zeros(out, start);
}

void append_shortest(std::string& out, double v) {
    char buf[64];
    // Fixed notation: G-code has no exponent syntax (E is a word letter).
    auto res = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed);
    if (res.ec != std::errc{}) res = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, 6);
    auto start = out.size();
    out.append(buf, res.ptr);
    trim_zeros(out, start);
}

double round_to(double v, int decimals) {
    const double scale = std::pow(10.0, decimals);
    return std::nearbyint(v * scale) / scale;
}

}  // namespace xlate5
