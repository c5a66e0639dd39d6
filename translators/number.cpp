// Number text <-> double (no stage). What it may call: see number.hpp.
#include "translators/number.hpp"

#include <charconv>
#include <cstring>
#include <cmath>
#include <string>

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

void append_units(std::string& out, long long units, int decimals) {
    char buf[kUnitsChars];
    out.append(buf, write_units(buf, units, decimals));
}

namespace {

constexpr char kPairs[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

// The digits of v at p, left to right.
inline char* write_integer(char* p, unsigned long long v) {
    int n = 1;
    for (unsigned long long t = 10; n < 20 && v >= t; t *= 10) ++n;
    char* q = p + n;
    while (v >= 100) {
        const unsigned r = unsigned(v % 100);
        v /= 100;
        *--q = kPairs[2 * r + 1];
        *--q = kPairs[2 * r];
    }
    if (v >= 10) {
        *--q = kPairs[2 * v + 1];
        *--q = kPairs[2 * v];
    } else {
        *--q = char('0' + v);
    }
    return p + n;
}

// write_units for D decimals (1 to 9), which the compiler divides by multiplying: the integer
// part and the fraction split once, the fraction's trailing zeros dropped on a 32-bit value.
template <int D>
char* write_decimals(char* p, unsigned long long u) {
    constexpr unsigned long long kScale = [] {
        unsigned long long s = 1;
        for (int i = 0; i < D; ++i) s *= 10;
        return s;
    }();
    unsigned frac = unsigned(u % kScale);
    p = write_integer(p, u / kScale);
    if (frac == 0) return p;
    int d = D;
    while (frac % 10 == 0) {
        frac /= 10;
        --d;
    }
    *p++ = '.';
    char* q = p + d;  // d digits, leading zeros included (0.05)
    for (; q - p >= 2;) {
        const unsigned r = frac % 100;
        frac /= 100;
        *--q = kPairs[2 * r + 1];
        *--q = kPairs[2 * r];
    }
    if (q > p) *--q = char('0' + frac);
    return p + d;
}

}  // namespace

char* write_units(char* out, long long units, int decimals) {
    if (units == 0) {
        *out = '0';
        return out + 1;
    }
    if (decimals >= 1 && decimals <= 9) {
        char* p = out;
        if (units < 0) *p++ = '-';
        const unsigned long long u = units < 0 ? 0ull - static_cast<unsigned long long>(units) : static_cast<unsigned long long>(units);
        switch (decimals) {
            case 1: return write_decimals<1>(p, u);
            case 2: return write_decimals<2>(p, u);
            case 3: return write_decimals<3>(p, u);
            case 4: return write_decimals<4>(p, u);
            case 5: return write_decimals<5>(p, u);
            case 6: return write_decimals<6>(p, u);
            case 7: return write_decimals<7>(p, u);
            case 8: return write_decimals<8>(p, u);
            default: return write_decimals<9>(p, u);
        }
    }
    const bool negative = units < 0;
    unsigned long long u = negative ? 0ull - static_cast<unsigned long long>(units) : static_cast<unsigned long long>(units);
    int d = decimals;
    while (d > 0 && u % 10 == 0) {  // trailing zeros of the fraction are not printed
        u /= 10;
        --d;
    }
    // Other decimals: written right to left into a small buffer, then copied: the d fraction
    // digits (leading zeros included: 0.05), the point, then the integer part two digits at a time.
    char buf[24 + kUnitsChars];
    char* const end = buf + 24;
    char* p = end;
    if (d > 0) {
        int k = d;
        for (; k >= 2; k -= 2) {
            const unsigned r = unsigned(u % 100);
            u /= 100;
            *--p = kPairs[2 * r + 1];
            *--p = kPairs[2 * r];
        }
        if (k == 1) {
            *--p = char('0' + u % 10);
            u /= 10;
        }
        *--p = '.';
    }
    while (u >= 100) {
        const unsigned r = unsigned(u % 100);
        u /= 100;
        *--p = kPairs[2 * r + 1];
        *--p = kPairs[2 * r];
    }
    if (u >= 10) {
        *--p = kPairs[2 * u + 1];
        *--p = kPairs[2 * u];
    } else {
        *--p = char('0' + u);
    }
    if (negative) *--p = '-';
    // At most 19 digits, a point and a sign, at the end of buf: the kUnitsChars bytes from p stay
    // inside it, and are copied whole.
    std::memcpy(out, p, kUnitsChars);
    return out + (end - p);
}

namespace {
constexpr int kMaxDecimals = 17;  // a double has no more significant decimals than this

void check_writable(double v) {
    if (std::abs(v) <= kMaxWritten) return;
    char text[32];
    auto res = std::to_chars(text, text + sizeof text, v, std::chars_format::general, 6);  // "inf", "nan", "1e+200"
    throw UnwritableNumber("a value of " + std::string(text, res.ptr) +
                           " cannot be written: G-code numbers are finite and at most 1e9 in magnitude "
                           "(check the machine's parameters, its compensation terms and this line's numbers)");
}
}  // namespace

void append_fixed(std::string& out, double v, int decimals) {
    // The hot path of every joint word; rounds half away from zero at the last printed digit.
    long long units = 0;
    if (to_units(v, decimals, units)) {
        append_units(out, units, decimals);
        return;
    }
    check_writable(v);
    if (decimals < 0 || decimals > kMaxDecimals) throw UnwritableNumber("cannot write " + std::to_string(decimals) + " decimals (0 to 17)");
    // |v| <= 1e9 with at most 17 decimals: at most 1 + 10 + 1 + 17 characters.
    char buf[64];
    auto res = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
    if (res.ec != std::errc{}) throw UnwritableNumber("a value cannot be written in fixed notation");
    auto start = out.size();
    out.append(buf, res.ptr);
    trim_zeros(out, start);
}

void append_shortest(std::string& out, double v) {
    check_writable(v);
    char buf[64];
    // Fixed notation: G-code has no exponent syntax (E is a word letter). Only a value below
    // about 1e-40 has no shortest fixed form within 64 characters; it is 0 to 6 decimals.
    auto res = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed);
    if (res.ec != std::errc{}) res = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, 6);
    if (res.ec != std::errc{}) throw UnwritableNumber("a value cannot be written in fixed notation");
    auto start = out.size();
    out.append(buf, res.ptr);
    trim_zeros(out, start);
}


void unwritable_word(char letter, const UnwritableNumber& e) {
    throw UnwritableNumber(std::string("word ") + letter + ": " + e.what());
}

}  // namespace xlate5
