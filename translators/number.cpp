// SPDX-License-Identifier: GPL-3.0-or-later
// Number text <-> double (no stage). What it may call: see number.hpp.
#include "translators/number.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
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

// The text of 0 to 999 (a joint's integer part, mostly).
extern constexpr std::array<ShortText, 1000> kIntegerText = [] {
    std::array<ShortText, 1000> t{};
    for (int v = 0; v < 1000; ++v) {
        const int n = v >= 100 ? 3 : v >= 10 ? 2 : 1;
        for (int k = n - 1, x = v; k >= 0; --k, x /= 10) t[std::size_t(v)].text[k] = char('0' + x % 10);
        t[std::size_t(v)].size = static_cast<unsigned char>(n);
    }
    return t;
}();

// Three decimals, the joints' usual count: each fraction's text (point, digits without the
// trailing zeros; nothing for 0) from a table.
extern constexpr std::array<ShortText, 1000> kFraction3Text = [] {
    std::array<ShortText, 1000> t{};
    for (int f = 1; f < 1000; ++f) {
        int digits = 3, v = f;
        while (v % 10 == 0) v /= 10, --digits;
        ShortText& e = t[std::size_t(f)];
        e.text[0] = '.';
        for (int k = digits; k >= 1; --k, v /= 10) e.text[k] = char('0' + v % 10);
        e.size = static_cast<unsigned char>(digits + 1);
    }
    return t;
}();

namespace {

constexpr char kPairs[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

}  // namespace

// Three digits of 0 to 999 with their leading zeros ("007"): the lower part of a number below
// a million.
extern constexpr std::array<ShortText, 1000> kThreeDigits = [] {
    std::array<ShortText, 1000> t{};
    for (int v = 0; v < 1000; ++v) {
        for (int k = 2, x = v; k >= 0; --k, x /= 10) t[std::size_t(v)].text[k] = char('0' + x % 10);
        t[std::size_t(v)].size = 3;
    }
    return t;
}();

namespace {

// The digits of v at p, left to right; below 1000 from the table.
inline char* write_integer(char* p, unsigned long long v) {
    if (v < 1000) return put_short(p, kIntegerText[v]);
    if (v < 1000000) return put_short(put_short(p, kIntegerText[v / 1000]), kThreeDigits[v % 1000]);  // (a feed, mostly)
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

// A point and the fraction's `digits` digits (leading zeros included: 0.05), its trailing
// zeros dropped; nothing at all for a zero fraction.
inline char* write_fraction(char* p, unsigned long long frac, int digits) {
    if (frac == 0) return p;
    while (frac % 10 == 0) {
        frac /= 10;
        --digits;
    }
    *p++ = '.';
    char* q = p + digits;
    while (q - p >= 2) {
        const unsigned r = unsigned(frac % 100);
        frac /= 100;
        *--q = kPairs[2 * r + 1];
        *--q = kPairs[2 * r];
    }
    if (q > p) *--q = char('0' + frac);
    return p + digits;
}

// The integer part and the fraction split once; for D decimals known here (1 to 9: what
// to_units gives) the compiler divides by multiplying.
template <int D>
char* write_decimals(char* p, unsigned long long u) {
    constexpr unsigned long long kScale = [] {
        unsigned long long s = 1;
        for (int i = 0; i < D; ++i) s *= 10;
        return s;
    }();
    return write_fraction(write_integer(p, u / kScale), u % kScale, D);
}

template <>
char* write_decimals<3>(char* p, unsigned long long u) {
    p = write_integer(p, u / 1000);
    return put_short(p, kFraction3Text[u % 1000]);
}

}  // namespace

char* write_units_general(char* out, long long units, int decimals) {
    if (units == 0) {
        *out = '0';
        return out + 1;
    }
    char* p = out;
    if (units < 0) *p++ = '-';
    const unsigned long long u = units < 0 ? 0ull - static_cast<unsigned long long>(units) : static_cast<unsigned long long>(units);
    switch (decimals) {
        case 0: return write_integer(p, u);
        case 1: return write_decimals<1>(p, u);
        case 2: return write_decimals<2>(p, u);
        case 3: return write_decimals<3>(p, u);
        case 4: return write_decimals<4>(p, u);
        case 5: return write_decimals<5>(p, u);
        case 6: return write_decimals<6>(p, u);
        case 7: return write_decimals<7>(p, u);
        case 8: return write_decimals<8>(p, u);
        case 9: return write_decimals<9>(p, u);
        default: {  // 10 to 18
            unsigned long long scale = 1;
            for (int i = 0; i < decimals; ++i) scale *= 10;
            return write_fraction(write_integer(p, u / scale), u % scale, decimals);
        }
    }
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
