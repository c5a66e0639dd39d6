// SPDX-License-Identifier: GPL-3.0-or-later
// Number text <-> double, without locale and without allocation (the hot path of every line).
// No stage: the lexer and the emitters call it. Calls nothing.
#pragma once
#include <array>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>

#include "translators/error.hpp"

namespace xlate5 {

// A number passed on from the input (E, F): written as it was typed, unless it was converted
// (inches), in which case `text` is empty and the shortest exact form of `value` is written.
struct PassedNumber {
    double value = 0;
    std::string_view text;
    int decimals = -1;  // for a computed value: digits after the point (-1: shortest exact form)
};

// Digits after the point of a number as typed ("-1.250" -> 3, "7" -> 0); -1 for text that is
// not a plain decimal (empty, as a computed number's is, or other characters).
inline int plain_decimals(std::string_view t) {
    const std::size_t dot = t.find('.');
    for (std::size_t i = 0; i < t.size(); ++i)
        if (i != dot && !(t[i] >= '0' && t[i] <= '9') && !(i == 0 && (t[i] == '-' || t[i] == '+'))) return -1;
    return t.empty() ? -1 : dot == std::string_view::npos ? 0 : int(t.size() - dot - 1);
}

// Largest magnitude ever written into G-code, the same bound the lexer puts on input numbers:
// far beyond any machine, and small enough that firmware reading it as a float stays sane.
inline constexpr double kMaxWritten = 1e9;

// A value that must not be written: not finite, or beyond kMaxWritten. A LineError (column 1:
// the line as a whole), so the translator reports it as an InputError naming the input line
// that produced it, and nothing of that line is written.
class UnwritableNumber : public LineError {
public:
    explicit UnwritableNumber(const std::string& message) : LineError(1, message) {}
};

// Rethrows e naming the G-code word it was for.
[[noreturn]] void unwritable_word(char letter, const UnwritableNumber& e);

// Appends v with at most `decimals` digits after the point, trailing zeros and a bare point
// removed, and "-0" written as "0" (what firmware parsers and diff tools expect). Throws
// UnwritableNumber for a non-finite v, |v| > kMaxWritten or decimals outside 0..17.
void append_fixed(std::string& out, double v, int decimals);

// Appends the shortest text that reads back as exactly v (for values passed through, such as E);
// values too small for fixed notation's 64 characters are written to 6 decimals. Throws
// UnwritableNumber as append_fixed.
void append_shortest(std::string& out, double v);

// Half away from zero, as llround, without the library call or a branch: the largest double
// below 0.5 added with scaled's sign, then truncated. (With 0.5 itself the sum rounds up for
// 0.5 - 2^-54, the one double in [0.25, 0.5) whose sum with 0.5 is a tie in [0.5, 1): it gave 1
// where llround gives 0. With the double below 0.5 an exact half still sums past the integer
// above it, or ties to it in a coarser binade, and anything below a half stays below: the same as
// llround for every |scaled| < 1e15, as test_stream checks at each n + 0.5 and its neighbours.)
// For |scaled| < 1e15 (fits exactly), not NaN.
inline long long round_half_away(double scaled) {
    return static_cast<long long>(scaled + std::copysign(0.49999999999999994, scaled));
}

// v in units of 10^-decimals, rounded half away from zero: what append_fixed prints. False if
// out of the fast range or not writable (then append_fixed falls back to std::to_chars, or throws).
// Inline: the emitter calls it for every joint of every line.
inline bool to_units(double v, int decimals, long long& units) {
    static constexpr double kPow10[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
    if (decimals < 0 || decimals > 9 || !(std::abs(v) <= kMaxWritten)) return false;  // NaN too
    const double scaled = v * kPow10[decimals];
    if (!(std::abs(scaled) < 1e15)) return false;
    units = round_half_away(scaled);
    return true;
}
// write_units_general: writes units * 10^-decimals (decimals 0 to 18) with trailing fraction zeros removed at p and
// returns the end of the text: at most 21 characters, no terminator. It may write scratch bytes
// past that end, never past p + kUnitsChars: give it that much room. append_units appends the
// same to a string. (write_units, below, is inline for the usual case; this is any case.)
inline constexpr std::size_t kUnitsChars = 24;
char* write_units_general(char* p, long long units, int decimals);
void append_units(std::string& out, long long units, int decimals);

// A text of at most four bytes and its length: an entry of the tables below. Eight bytes, so an
// entry's address is the index shifted (no multiply by five).
struct ShortText {
    char text[4];
    unsigned char size;
    unsigned char unused[3];
};
static_assert(sizeof(ShortText) == 8);
// The text of 0 to 999 ("7", "42"), and of a three-decimal fraction 0 to 999 (".05", ".125";
// nothing for 0), from number.cpp.
extern const std::array<ShortText, 1000> kIntegerText;
extern const std::array<ShortText, 1000> kFraction3Text;
// Three digits of 0 to 999 with their leading zeros ("007"): the lower part of a number below a million.
extern const std::array<ShortText, 1000> kThreeDigits;

// The text at p: four bytes copied at once (the bytes past size are scratch: see kUnitsChars),
// the length added.
inline char* put_short(char* p, const ShortText& t) {
    std::memcpy(p, t.text, 4);
    return p + t.size;
}

// The text write_units_general writes, the usual cases inline, no call: three decimals below
// 1000 in magnitude (the joints), one decimal below a million (a feed); any other case is passed on.
// write_units3_small: three decimals, |units| < 1000000 (the caller has checked): a sign and two
// table entries. write_units1_small: one decimal, |units| < 10000000 (a feed): the integer part
// from one or two entries, then the point and the digit, both written and kept only when not 0.
inline char* write_units3_small(char* p, long long units) {
    *p = '-';
    p += units < 0;
    const unsigned u = unsigned(units < 0 ? -units : units);
    return put_short(put_short(p, kIntegerText[u / 1000]), kFraction3Text[u % 1000]);
}
inline char* write_units1_small(char* p, long long units) {
    *p = '-';
    p += units < 0;
    const unsigned u = unsigned(units < 0 ? -units : units);
    const unsigned i = u / 10, f = u % 10;
    p = i < 1000 ? put_short(p, kIntegerText[i]) : put_short(put_short(p, kIntegerText[i / 1000]), kThreeDigits[i % 1000]);
    p[0] = '.';
    p[1] = char('0' + f);
    return p + (f != 0 ? 2 : 0);
}

inline char* write_units(char* p, long long units, int decimals) {
    if (decimals == 3 && units > -1000000 && units < 1000000) return write_units3_small(p, units);
    if (decimals == 1 && units > -10000000 && units < 10000000) return write_units1_small(p, units);
    return write_units_general(p, units, decimals);
}

}  // namespace xlate5
