// SPDX-License-Identifier: GPL-3.0-or-later
// The lexer stage: one line -> words. What it may call: see gcode_lexer.hpp.
#include "translators/inputs/gcode_lexer.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>

#include "translators/error.hpp"

namespace xlate5 {

namespace {

bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_alpha(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }
bool is_blank(char c) { return c == ' ' || c == '\t'; }
char upper(char c) { return (c >= 'a' && c <= 'z') ? char(c - 'a' + 'A') : c; }

[[noreturn]] void fail(std::size_t index, const std::string& message) {
    throw LineError(std::uint32_t(index + 1), message);
}

std::string byte_name(unsigned char c) {
    char buf[8];
    std::snprintf(buf, sizeof buf, "0x%02X", c);
    return buf;
}

// Rejects bytes that are not text anywhere in the line, so a binary file or a garbled
// transfer stops at its first bad byte instead of producing moves.
void check_text(std::string_view line, std::size_t from) {
    for (std::size_t i = from; i < line.size(); ++i) {
        const auto c = static_cast<unsigned char>(line[i]);
        if ((c < 0x20 && c != '\t') || c == 0x7F) fail(i, "non-text byte " + byte_name(c));
    }
}

// Commands whose argument is free text (messages, file names), not words.
bool takes_text(double m_value) {
    for (int m : {23, 28, 30, 32, 117, 118, 928})
        if (m_value == m) return true;
    return false;
}

// After a number ending at `i`: an 'E' or 'e', an optional sign and digits with no '.' after them
// read as an exponent as well as a separate E word ("X1.5e-05": 0.000015, or X1.5 and a retract
// E-05). Command words (G M T N) are codes, never written with an exponent, so "G1E-1" is not
// ambiguous (the lexer asks only after other words); nor is "X1E0.5" (an exponent has no point).
// Unless the file is declared compact the ambiguous form is refused, so a CAM program's float
// never turns into extrusion by accident.
void check_exponent_like(std::string_view s, std::size_t i, char letter, std::size_t letter_index) {
    if (i >= s.size() || (s[i] != 'E' && s[i] != 'e')) return;
    std::size_t k = i + 1;
    if (k < s.size() && (s[k] == '+' || s[k] == '-')) ++k;
    const std::size_t digits = k;
    while (k < s.size() && is_digit(s[k])) ++k;
    if (k == digits || (k < s.size() && s[k] == '.')) return;
    const std::string written{s.substr(letter_index, std::min<std::size_t>(k - letter_index, 32))};
    const std::string number{s.substr(letter_index + 1, i - letter_index - 1)};
    const std::string exponent{s.substr(i, k - i)};
    fail(i, "'" + written + "' is ambiguous: it reads as a number with an exponent, or as " + letter + number +
                " followed by the word " + exponent + " (extrusion). G-code has no exponents: write the number without one, or put a "
                "blank before a separate E word (" + letter + number + " " + exponent +
                "); a file written without blanks may declare itself with a line '; " + std::string(kCompactDeclaration) +
                "' at its top (or the command line's --compact-words)");
}

// The value of a decimal digit, or more than 9 for any other byte (one test: '0'..'9' only).
inline unsigned digit_value(char c) { return unsigned(static_cast<unsigned char>(c)) - unsigned('0'); }

// Appends the run of digits at `k` to `mantissa`, two at a time (a byte after a digit can be
// read: the line's copy ends with a NUL).
inline void read_digit_run(const char* s, std::size_t& k, std::uint64_t& mantissa) {
    for (;;) {
        const unsigned d0 = digit_value(s[k]);
        if (d0 > 9) return;
        const unsigned d1 = digit_value(s[k + 1]);
        if (d1 > 9) {
            mantissa = mantissa * 10 + d0;
            ++k;
            return;
        }
        mantissa = mantissa * 100 + (d0 * 10 + d1);
        k += 2;
    }
}

// The common number, "[+-]digits[.digits]" with 1 to 19 digits and within the range limit, read
// at `i` of `s`, which must end with a NUL (the lexer's copy of the line): the digit loops stop
// there. False, `i` unchanged, for any other form; read_other_number then reads it.
// Up to 15 significant digits as an integer, then one division by a power of ten: both are
// exact in a double, and IEEE division rounds correctly, so this is the same value std::from_chars
// gives. (Eight bytes at a time with integer tricks was tried: more instructions, G-code's runs
// being one to five digits.)
inline bool read_plain_number(const char* s, std::size_t& i, double& value) {
    std::size_t k = i;
    const bool negative = s[k] == '-';
    if (negative || s[k] == '+') ++k;
    std::uint64_t mantissa = 0;  // wraps past 19 digits, which are not read here
    const std::size_t int_start = k;
    read_digit_run(s, k, mantissa);
    std::size_t digits = k - int_start, decimals = 0;
    if (s[k] == '.') {
        const std::size_t frac_start = ++k;
        read_digit_run(s, k, mantissa);
        decimals = k - frac_start;
        digits += decimals;
    }
    static constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,
                                        1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19};
    // The largest mantissa read here for each count of decimals: below 1e15 (exact), and at most
    // 1e9 * 10^decimals, which holds exactly when the rounded quotient is at most 1e9 (a quotient
    // above 1e9 is so by at least 10^-decimals, more than half its ulp). The check is on the
    // integers, so no branch waits for the division.
    static constexpr std::uint64_t kMost[] = {
        1000000000ull,      10000000000ull,     100000000000ull,    1000000000000ull,   10000000000000ull,
        100000000000000ull, 999999999999999ull, 999999999999999ull, 999999999999999ull, 999999999999999ull,
        999999999999999ull, 999999999999999ull, 999999999999999ull, 999999999999999ull, 999999999999999ull,
        999999999999999ull, 999999999999999ull, 999999999999999ull, 999999999999999ull, 999999999999999ull};
    if (digits - 1 >= 19 || mantissa > kMost[decimals]) return false;  // (digits 0 wraps: not read here)
    const double v = double(std::int64_t(mantissa)) / kPow10[decimals];  // (signed: one instruction)
    value = negative ? -v : v;
    i = k;
    return true;
}

// The letter bit (letter_bit) of each byte that is a letter, either case, but M and N (which
// read_common_words leaves to the general reading); 0 for any other byte.
constexpr auto kCommonLetterBits = [] {
    std::array<std::uint32_t, 256> bits{};
    for (int c = 'A'; c <= 'Z'; ++c)
        if (c != 'M' && c != 'N') bits[std::size_t(c)] = bits[std::size_t(c - 'A' + 'a')] = letter_bit(char(c));
    return bits;
}();

// The words of the bulk of a program, read from `i` of `s` in a loop of their own (few
// variables, so they all stay in registers): a letter other than M and N (which have more to
// them), right after it "[-]digits[.digits]" with 1 to 9 digits, then no E (which could be an
// exponent) and, after G and T, a code in range. Returns where it stopped: at anything else, from
// its letter on, for the general reading in lex_rest (which then reads the same thing, or refuses
// it). `s`: the line's copy (a NUL after it); `line`: the line, where words point. The caller
// makes room for every word the rest of the line can hold (each has two characters at least).
// The value is read_plain_number's (the same mantissa and division); nine digits are below 1e9
// at every count of decimals, so no range test.
[[gnu::always_inline]] inline std::size_t read_common_words(const char* s, std::size_t i, const char* line, Word*& next_out,
                                                std::uint32_t& letters_out) {
    // 10^decimals, then the same negated: the sign is the division's (IEEE division is exact in
    // sign, so m / -10^k is -(m / 10^k), and -0.0 for m = 0 as read_plain_number gives).
    static constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  0, 0, 0, 0, 0, 0,
                                        -1e0, -1e1, -1e2, -1e3, -1e4, -1e5, -1e6, -1e7, -1e8, -1e9, 0, 0, 0, 0, 0, 0};
    constexpr std::uint32_t kCodes = letter_bit('G') | letter_bit('T');
    // A byte's digit value, or more than 9 (64 bits: no widening in the loops; '.' is -2).
    auto digit = [](char c) { return std::uint64_t(static_cast<unsigned char>(c)) - '0'; };
    Word* next = next_out;
    std::uint32_t letters = letters_out;
    unsigned c = static_cast<unsigned char>(s[i]);
    for (;;) {
        const std::uint32_t bit = kCommonLetterBits[c];
        if (bit == 0) break;
        std::size_t k = i + 1;
        std::uint64_t d = digit(s[k]);
        std::size_t sign = 0;  // 16 when negative: the row of kPow10
        if (__builtin_expect(d > 9, 0)) {
            if (d != std::uint64_t('-' - '0')) break;
            d = digit(s[++k]);
            if (d > 9) break;
            sign = 16;
        }
        const char* const int_start = s + k;
        const char* q = int_start;
        std::uint64_t mantissa = d;
        for (;;) {
            d = digit(q[1]);
            if (d > 9) break;
            mantissa = mantissa * 10 + d;
            ++q;
        }
        ++q;
        std::size_t decimals = 0, digits = std::size_t(q - int_start);
        if (d == std::uint64_t(-2)) {  // '.'
            const char* const dot = q;
            for (;;) {
                d = digit(q[1]);
                if (d > 9) break;
                mantissa = mantissa * 10 + d;
                ++q;
            }
            ++q;
            decimals = std::size_t(q - dot) - 1;
            digits += decimals;
        }
        k = std::size_t(q - s);
        if (digits > 9) break;
        const double value = double(std::int64_t(mantissa)) / kPow10[sign + decimals];
        if ((bit & kCodes) && !(std::abs(value) < kMaxCode)) break;
        // The word is written at once, but counted only once the byte after the number is known
        // not to be 'E' or 'e' (there is room for it in any case). d is that byte's digit value.
        *next = Word{.value = value, .text = std::string_view(line + i + 1, k - i - 1), .column = std::uint32_t(i + 1),
                     .letter = char(c & ~0x20u), .has_value = true};
        if (d == std::uint64_t(' ' - '0')) {  // the common separator, skipped at once
            i = k + 1;
            c = static_cast<unsigned char>(s[i]);
        } else {
            if ((d | 32) == 53) break;  // 'E' (21) or 'e' (53)
            i = k;
            c = unsigned(d) + unsigned('0');
        }
        ++next;
        letters |= bit;
    }
    next_out = next;
    letters_out = letters;
    return i;
}

// Any other number at `i`: "[+-]digits[.digits]" or "[+-].digits" of any length (std::from_chars),
// out of range, or no number at all. G-code has no exponent (E is a word). A letter followed by
// no number is a flag (has_value false); whether a flag is allowed is the interpreter's call,
// since it depends on the command.
double read_other_number(std::string_view s, std::size_t& i, char letter, std::size_t letter_index, bool& has_value) {
    has_value = true;
    const std::size_t start = i;
    bool negative = false;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) {
        negative = s[i] == '-';
        ++i;
    }
    const std::size_t digits_start = i;
    while (i < s.size() && is_digit(s[i])) ++i;
    if (i < s.size() && s[i] == '.') {
        ++i;
        while (i < s.size() && is_digit(s[i])) ++i;
    }
    const std::string_view digits = s.substr(digits_start, i - digits_start);
    if (digits.empty() || digits == ".") {
        std::size_t j = digits_start;
        while (j < s.size() && is_alpha(s[j])) ++j;
        std::string word{s.substr(digits_start, j - digits_start)};
        for (auto& ch : word) ch = upper(ch);
        if (word.rfind("NAN", 0) == 0 || word.rfind("INF", 0) == 0)
            fail(start, std::string("word ") + letter + " has a value that is not a finite number");
        if (i != start) fail(letter_index, std::string("word ") + letter + " has a sign but no number");
        if (j > digits_start && digits_start == letter_index + 1) {
            // "TOOL PATH/..." (APT CL data) or "Xabc": letters run on, so this is not a flag.
            // (Letters after a blank start the next word: "G28 X Y" is two flags.)
            std::string text{s.substr(letter_index, std::min<std::size_t>(j - letter_index, 16))};
            fail(letter_index, "'" + text + "' is not a G-code word (a letter must be followed by a number)");
        }
        if (i < s.size() && s[i] == '"') {  // RepRapFirmware string argument: P"name" ("" is a quote)
            const std::size_t open = i++;
            for (;;) {
                if (i >= s.size()) fail(open, "string '\"' is not closed on this line");
                if (static_cast<unsigned char>(s[i]) < 0x20 || s[i] == 0x7F) fail(i, "non-text byte " + byte_name(static_cast<unsigned char>(s[i])));
                if (s[i] == '"' && i + 1 < s.size() && s[i + 1] == '"') i += 2;
                else if (s[i++] == '"') break;
                else continue;
            }
        }
        has_value = false;
        return std::numeric_limits<double>::quiet_NaN();
    }
    double value = 0;
    auto res = std::from_chars(digits.data(), digits.data() + digits.size(), value, std::chars_format::fixed);
    if (res.ec != std::errc{} || res.ptr != digits.data() + digits.size() || !(value <= kMaxNumber))
        fail(start, std::string("number of word ") + letter + " is out of range (limit 1e9)");
    return negative ? -value : value;
}

// The body of a comment-only line: is it the compact declaration?
bool declares_compact(std::string_view body) {
    if (body.size() >= 2 && body.front() == '(' && body.back() == ')') body = body.substr(1, body.size() - 2);
    else if (!body.empty() && body.front() == ';') body.remove_prefix(1);
    else return false;
    while (!body.empty() && is_blank(body.front())) body.remove_prefix(1);
    while (!body.empty() && is_blank(body.back())) body.remove_suffix(1);
    if (body.size() != kCompactDeclaration.size()) return false;
    for (std::size_t k = 0; k < body.size(); ++k)
        if (upper(body[k]) != upper(kCompactDeclaration[k])) return false;
    return true;
}

void skip_paren_comment(std::string_view s, std::size_t& i) {
    const std::size_t open = i;
    while (i < s.size() && s[i] != ')') {
        const auto c = static_cast<unsigned char>(s[i]);
        if ((c < 0x20 && c != '\t') || c == 0x7F) fail(i, "non-text byte " + byte_name(c));
        ++i;
    }
    if (i == s.size()) fail(open, "comment '(' is not closed on this line");
    ++i;
}

// Room for more words: the room doubles, the words so far kept. `next` and `room_end` follow.
void grow_words(Block& out, Word*& next, Word*& room_end) {
    const std::size_t used = std::size_t(next - out.word_room.data());
    out.word_room.resize(std::max<std::size_t>(16, 2 * out.word_room.size()));
    next = out.word_room.data() + used;
    room_end = out.word_room.data() + out.word_room.size();
}

// Letters with checks of their own after the number: G M T are codes, N a line number.
constexpr std::uint32_t kCheckedLetters = letter_bit('G') | letter_bit('M') | letter_bit('T') | letter_bit('N');

// After a text-taking M code's number at `i`: the rest of the line is its argument, passed on as
// it is; only a trailing *checksum still belongs to the transport. Returns where that starts (npos: none).
std::size_t text_argument_checksum(std::string_view s, std::size_t i) {
    const std::size_t n = s.size();
    check_text(s, i);
    const std::size_t star = s.rfind('*');
    if (star == std::string_view::npos || star < i) return std::string_view::npos;
    std::size_t k = star + 1;
    while (k < n && is_digit(s[k])) ++k;
    const bool digits = k > star + 1;
    while (k < n && is_blank(s[k])) ++k;
    return digits && k == n ? star : std::string_view::npos;
}

// A checksum at `i` ('*'): digits, then nothing but blanks and comments. `i` moves past them.
void read_checksum(std::string_view s, std::size_t& i) {
    const std::size_t n = s.size(), star = i++;
    const std::size_t digits = i;
    while (i < n && is_digit(s[i])) ++i;
    if (i == digits) fail(star, "checksum '*' has no number");
    while (i < n && is_blank(s[i])) ++i;
    check_text(s, i);
    if (i < n && s[i] != ';' && s[i] != '(') fail(i, "text after the checksum");
}

// The block's body once its words are read: from the first word or an earlier comment to the
// last word or a later comment, a checksum cut off, trailing blanks too.
void set_body(std::string_view line, Block& out, std::size_t body_begin, std::size_t body_end, std::size_t checksum_at) {
    if (out.word_count > 0) {
        body_begin = std::min<std::size_t>(body_begin, out.word_room[0].column - 1);
        const std::string_view last = out.word_room[out.word_count - 1].text;
        body_end = std::max<std::size_t>(body_end, std::size_t(last.data() + last.size() - line.data()));
    }
    if (body_begin == std::string_view::npos) {
        out.body = {};
        return;
    }
    // A checksum ends the body (a host's checksummed line carries no comment worth keeping).
    if (checksum_at != std::string_view::npos && checksum_at < body_end) body_end = checksum_at;
    if (body_end <= body_begin) {
        out.body = {};
        return;
    }
    std::string_view body(line.data() + body_begin, body_end - body_begin);  // (body_end <= n)
    while (!body.empty() && is_blank(body.back())) body.remove_suffix(1);
    out.body = body;
    if (out.word_count == 0 && out.has_comment && !out.percent && declares_compact(body)) out.compact_words = true;
}

// After a '%' at `i` that starts a line's words: where the rest (blanks, then the end or a
// comment) begins, or npos when more follows (the '%' is then unexpected).
std::size_t percent_end(std::string_view s, std::size_t i) {
    std::size_t j = i + 1;
    while (j < s.size() && is_blank(s[j])) ++j;
    if (j != s.size() && s[j] != ';' && s[j] != '(') return std::string_view::npos;
    check_text(s, j);
    return j;
}

// A G M T code or N line number: it has a number, and a code one below kMaxCode.
void check_code_word(char letter, std::size_t letter_index, bool has_value, double value) {
    if (!has_value) fail(letter_index, std::string("word ") + letter + " has no number");
    if (letter != 'N' && !(std::abs(value) < kMaxCode)) fail(letter_index, std::string("word ") + letter + " is a code, and codes are below 100000");
}

// A character at `i` that starts no word, blank, comment, checksum or '%' line.
[[noreturn]] void fail_unexpected(std::string_view s, std::size_t i) {
    const char c = s[i];
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) fail(i, "non-text byte " + byte_name(static_cast<unsigned char>(c)));
    if (static_cast<unsigned char>(c) >= 0x80) fail(i, "non-ASCII byte " + byte_name(static_cast<unsigned char>(c)) + " outside a comment");
    if (c == '#' || c == '[' || c == ']' || c == '=' || c == '<' || c == '>')
        fail(i, std::string("unexpected '") + c + "': parameters and expressions are not supported");
    fail(i, std::string("unexpected character '") + c + "'");
}

// The rest of lex_line from `i` (the words before it in the block's room up to `next`, their
// letters `letters`): any line but one of words read_common_words reads to its end. `scan` is the
// line with a NUL after it (Block::text's copy, or the line itself).
[[gnu::noinline]] void lex_rest(std::string_view line, const char* scan, Block& out, std::size_t i, Word* next, std::uint32_t letters) {
    const std::size_t n = line.size();
    const std::string_view s(scan, n);
    Word* room_end = out.word_room.data() + out.word_room.size();
    std::size_t body_begin = std::string_view::npos;  // of a comment or '%' before the first word
    std::size_t body_end = 0;                         // of a comment or '%' after the last word
    std::size_t checksum_at = std::string_view::npos;
    bool line_number_read = false;
    for (;;) {
        const char c = s[i];
        if (unsigned((static_cast<unsigned char>(c) | 0x20u) - 'a') < 26u) {  // a letter: the common case first, a word
            if (2 * std::size_t(room_end - next) >= n - i) {  // room for every word the line has left
                const std::size_t from = i;
                i = read_common_words(s.data(), i, line.data(), next, letters);
                if (i != from) continue;
            }
            const char letter = char(c & ~0x20);  // upper case
            const std::size_t letter_index = i++;
            while (is_blank(s[i])) ++i;  // RS274 allows "X 10"
            const std::size_t number_start = i;
            bool has_value = true;
            double value;
            if (!read_plain_number(s.data(), i, value)) value = read_other_number(s, i, letter, letter_index, has_value);
            if (kCheckedLetters & letter_bit(letter)) {
                check_code_word(letter, letter_index, has_value, value);
                if (letter == 'N' && next == out.word_room.data() && !line_number_read) {
                    // A leading line number belongs to the transport, not to the command.
                    line_number_read = true;
                    continue;
                }
            } else if ((s[i] | 0x20) == 'e' && has_value && !out.compact_words) {
                // Only an E right after the number can make it ambiguous (the common case: a
                // blank), and only after a word that is not a code or line number.
                check_exponent_like(s, i, letter, letter_index);
            }
            // (The body's end after words is found from the last word, once, at the end.)
            if (next == room_end) grow_words(out, next, room_end);
            letters |= letter_bit(letter);
            *next++ = Word{.value = value, .text = std::string_view(line.data() + number_start, i - number_start),
                           .column = std::uint32_t(letter_index + 1), .letter = letter, .has_value = has_value};
            if (letter == 'M' && takes_text(value)) {
                out.text_argument = true;
                body_end = n;
                checksum_at = text_argument_checksum(s, i);
                break;
            }
            if (s[i] == ' ') ++i;  // the common separator, skipped at once
            continue;
        }
        if (is_blank(c)) { ++i; continue; }
        if (i >= n) break;  // the NUL after the line
        if (c == ';' || c == '(') {
            out.has_comment = true;
            if (body_begin == std::string_view::npos) body_begin = i;
            if (c == ';') {
                body_end = n;
                check_text(s, i);
                break;
            }
            skip_paren_comment(s, i);
            body_end = i;
            continue;
        }
        if (c == '*') {
            checksum_at = i;
            read_checksum(s, i);
            continue;
        }
        const std::size_t percent = c == '%' && next == out.word_room.data() ? percent_end(s, i) : std::string_view::npos;
        if (percent == std::string_view::npos) fail_unexpected(s, i);
        out.percent = true;
        if (body_begin == std::string_view::npos) body_begin = i;
        body_end = i + 1;
        i = percent;
    }
    out.word_count = std::size_t(next - out.word_room.data());
    out.letters = letters;
    set_body(line, out, body_begin, body_end, checksum_at);
}

}  // namespace

void lex_line(std::string_view line, Block& out, bool nul_after) {
    out.word_count = 0;
    out.has_comment = false;
    out.percent = false;
    out.text_argument = false;
    // Non-text bytes are caught where each part of the line is read (one pass over the line).
    if (!line.empty() && line.back() == '\r') {
        line.remove_suffix(1);
        nul_after = false;  // a '\r' follows it now
    }

    // The line is read from a copy with a NUL after it (Block::text), or in place when one
    // follows it already: the scans of digits and blanks stop there, with no test of the line's
    // end at every character. A NUL inside the line stops them too, and is then refused as a
    // non-text byte where the line's end is tested. Words and body point into `line` itself,
    // which outlives the copy's next use.
    const std::size_t n = line.size();
    if (!nul_after) {
        if (out.text.size() < n + 1) out.text.resize(n + 1);
        if (n > 0) std::memcpy(out.text.data(), line.data(), n);
        out.text[n] = '\0';
    }
    const std::string_view s(nul_after ? line.data() : out.text.data(), n);

    // Room for every word of a line of up to 4096 characters (two at least each, "X1"), so that
    // read_common_words needs no test of the room (longer lines grow it word by word).
    if (2 * out.word_room.size() < n && n <= 4096) out.word_room.resize(n / 2 + 1);
    Word* next = out.word_room.data();
    std::uint32_t letters = 0;  // Block::letters
    std::size_t i = 0;
    if (2 * out.word_room.size() >= n) {
        i = read_common_words(s.data(), 0, line.data(), next, letters);
        if (i == n && next != out.word_room.data()) {
            // The whole line was such words (the bulk of a program): what lex_rest would give,
            // at once. The body runs from the first word, at the line's start, to the end of the
            // last, a digit or point.
            out.word_count = std::size_t(next - out.word_room.data());
            out.letters = letters;
            const std::string_view last = next[-1].text;
            out.body = std::string_view(line.data(), std::size_t(last.data() + last.size() - line.data()));
            return;
        }
    }
    lex_rest(line, s.data(), out, i, next, letters);
}

}  // namespace xlate5
