// Number text <-> double (no stage). What it may call: see number.hpp.
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

bool to_units(double v, int decimals, long long& units) {
    static constexpr double kPow10[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
    if (decimals < 0 || decimals > 9) return false;
    const double scaled = v * kPow10[decimals];
    if (!(std::abs(scaled) < 1e15)) return false;
    // Half away from zero, as llround, without the library call (|scaled| < 1e15 fits exactly).
    units = static_cast<long long>(scaled < 0 ? scaled - 0.5 : scaled + 0.5);
    return true;
}

void append_units(std::string& out, long long units, int decimals) {
    if (units == 0) {
        out += '0';
        return;
    }
    const bool negative = units < 0;
    unsigned long long u = negative ? 0ull - static_cast<unsigned long long>(units) : static_cast<unsigned long long>(units);
    int d = decimals;
    while (d > 0 && u % 10 == 0) {  // trailing zeros of the fraction are not printed
        u /= 10;
        --d;
    }
    // Digits right to left, two at a time; the point goes in after d fraction digits.
    static constexpr char kPairs[] =
        "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
        "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
        "8081828384858687888990919293949596979899";
    char digits[24];
    int n = 0;
    while (u >= 100) {
        const unsigned r = unsigned(u % 100);
        u /= 100;
        digits[n++] = kPairs[2 * r + 1];
        digits[n++] = kPairs[2 * r];
    }
    if (u >= 10) {
        digits[n++] = kPairs[2 * u + 1];
        digits[n++] = kPairs[2 * u];
    } else {
        digits[n++] = char('0' + u);
    }
    while (n <= d) digits[n++] = '0';  // 0.05 -> "0.05": leading zeros of the fraction
    char buf[32];
    char* p = buf;
    if (negative) *p++ = '-';
    for (int k = n - 1; k >= 0; --k) {
        *p++ = digits[k];
        if (k == d && d > 0) *p++ = '.';
    }
    out.append(buf, p);
}

void append_fixed(std::string& out, double v, int decimals) {
    // The hot path of every joint word; rounds half away from zero at the last printed digit.
    long long units = 0;
    if (to_units(v, decimals, units)) {
        append_units(out, units, decimals);
        return;
    }
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


}  // namespace xlate5
