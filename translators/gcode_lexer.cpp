// The lexer stage: one line -> words. What it may call: see gcode_lexer.hpp.
#include "translators/gcode_lexer.hpp"

#include <charconv>
#include <cmath>
#include <limits>
#include <cstdio>
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
bool takes_text(char letter, double value) {
    if (letter != 'M') return false;
    for (int m : {23, 28, 30, 32, 117, 118, 928})
        if (value == m) return true;
    return false;
}

// After a number ending at `i`: an 'E' or 'e', an optional sign and digits with no '.' after them
// read as an exponent as well as a separate E word ("X1.5e-05": 0.000015, or X1.5 and a retract
// E-05). Command words (G M T N) are codes, never written with an exponent, so "G1E-1" is not
// ambiguous; nor is "X1E0.5" (an exponent has no point). Unless the file is declared compact the
// ambiguous form is refused, so a CAM program's float never turns into extrusion by accident.
void check_exponent_like(std::string_view s, std::size_t i, char letter, std::size_t letter_index) {
    if (letter == 'G' || letter == 'M' || letter == 'T' || letter == 'N') return;
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

// The run of decimal digits at `i`, appended to `mantissa` (which wraps past 19 digits: the
// caller then does not use it), their count added to `count`. (Eight bytes at a time with
// integer tricks was tried: more instructions, G-code's runs being one to five digits.)
inline void read_digits(std::string_view s, std::size_t& i, std::uint64_t& mantissa, int& count) {
    const std::size_t from = i;
    for (; i < s.size(); ++i) {
        const unsigned digit = unsigned(static_cast<unsigned char>(s[i])) - unsigned('0');  // one test: '0'..'9' only
        if (digit > 9) break;
        mantissa = mantissa * 10 + digit;
    }
    count += int(i - from);
}
// Reads "[+-]digits[.digits]" or "[+-].digits" at `i`; G-code has no exponent (E is a word).
// A letter followed by no number is a flag (has_value false); whether a flag is allowed is the
// interpreter's call, since it depends on the command.
double read_number(std::string_view s, std::size_t& i, char letter, std::size_t letter_index, bool& has_value) {
    has_value = true;
    const std::size_t start = i;
    bool negative = false;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) {
        negative = s[i] == '-';
        ++i;
    }
    const std::size_t digits_start = i;
    // Fast path: up to 15 significant digits as an integer, then one division by a power of
    // ten; both are exact in a double, and IEEE division rounds correctly, so this is the same
    // value std::from_chars gives. Longer numbers (more than 19 digits written, or 16 significant
    // ones) take from_chars below, which gives the same value for any of them.
    std::uint64_t mantissa = 0;
    int decimals = 0, total = 0;
    read_digits(s, i, mantissa, total);
    if (i < s.size() && s[i] == '.') {
        ++i;
        read_digits(s, i, mantissa, decimals);
        total += decimals;
    }
    static constexpr double kPow10[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
                                        1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
    // The range check on the integers, not on the quotient, so no branch waits for the division:
    // with at most 15 digits, mantissa <= 1e9 * 10^decimals exactly when the rounded quotient is
    // <= 1e9 (a quotient above 1e9 is so by at least 10^-decimals, more than half its ulp).
    static constexpr std::uint64_t kLimit[] = {1000000000ull, 10000000000ull, 100000000000ull, 1000000000000ull,
                                               10000000000000ull, 100000000000000ull};
    if (total > 0 && total <= 19 && mantissa < 1000000000000000ull) {
        if (decimals < 6 && mantissa > kLimit[decimals]) fail(start, std::string("number of word ") + letter + " is out of range (limit 1e9)");
        const double v = double(mantissa) / kPow10[decimals];
        return negative ? -v : v;
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

}  // namespace

void lex_line(std::string_view line, Block& out) {
    out.words.clear();
    out.has_comment = false;
    out.percent = false;
    out.text_argument = false;
    // Non-text bytes are caught where each part of the line is read (one pass over the line).
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);

    std::size_t body_begin = std::string_view::npos;
    std::size_t body_end = 0;
    std::size_t checksum_at = std::string_view::npos;
    bool first_word = true;
    std::size_t i = 0;
    while (i < line.size()) {
        const char c = line[i];
        if (is_blank(c)) {
            ++i;
            continue;
        }
        if (is_alpha(c)) {  // the common case first: a word
            const char letter = upper(c);
            const std::size_t letter_index = i++;
            while (i < line.size() && is_blank(line[i])) ++i;  // RS274 allows "X 10"
            bool has_value = true;
            const std::size_t number_start = i;
            const double value = read_number(line, i, letter, letter_index, has_value);
            // Only an E right after the number can make it ambiguous (the common case: a blank).
            if (has_value && !out.compact_words && i < line.size() && (line[i] == 'E' || line[i] == 'e'))
                check_exponent_like(line, i, letter, letter_index);
            const bool code = letter == 'G' || letter == 'M' || letter == 'T';
            if ((code || letter == 'N') && !has_value) fail(letter_index, std::string("word ") + letter + " has no number");
            if (code && !(std::abs(value) < kMaxCode))
                fail(letter_index, std::string("word ") + letter + " is a code, and codes are below 100000");
            if (letter == 'N' && first_word) {
                // A leading line number belongs to the transport, not to the command.
                first_word = false;
                continue;
            }
            first_word = false;
            if (body_begin == std::string_view::npos) body_begin = letter_index;
            body_end = i;
            out.words.push_back(Word{letter, value, std::uint32_t(letter_index + 1), has_value, line.substr(number_start, i - number_start)});
            if (letter == 'M' && takes_text(letter, value)) {
                // The rest of the line is the argument, passed on as it is; only a trailing
                // *checksum still belongs to the transport.
                out.text_argument = true;
                body_end = line.size();
                check_text(line, i);
                const std::size_t star = line.rfind('*');
                if (star != std::string_view::npos && star >= i) {
                    std::size_t k = star + 1;
                    while (k < line.size() && is_digit(line[k])) ++k;
                    const bool digits = k > star + 1;
                    while (k < line.size() && is_blank(line[k])) ++k;
                    if (digits && k == line.size()) checksum_at = star;
                }
                break;
            }
            continue;
        }
        if (c == ';') {
            out.has_comment = true;
            if (body_begin == std::string_view::npos) body_begin = i;
            body_end = line.size();
            check_text(line, i);
            break;
        }
        if (c == '(') {
            out.has_comment = true;
            if (body_begin == std::string_view::npos) body_begin = i;
            skip_paren_comment(line, i);
            body_end = i;
            continue;
        }
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) fail(i, "non-text byte " + byte_name(static_cast<unsigned char>(c)));
        if (static_cast<unsigned char>(c) >= 0x80) fail(i, "non-ASCII byte " + byte_name(static_cast<unsigned char>(c)) + " outside a comment");
        if (c == '*') {
            // Checksum: digits, then nothing but blanks and comments.
            const std::size_t star = i++;
            checksum_at = star;
            const std::size_t digits = i;
            while (i < line.size() && is_digit(line[i])) ++i;
            if (i == digits) fail(star, "checksum '*' has no number");
            while (i < line.size() && is_blank(line[i])) ++i;
            check_text(line, i);
            if (i < line.size() && line[i] != ';' && line[i] != '(') fail(i, "text after the checksum");
            continue;
        }
        if (c == '%' && out.words.empty()) {
            std::size_t j = i + 1;
            while (j < line.size() && is_blank(line[j])) ++j;
            if (j == line.size() || line[j] == ';' || line[j] == '(') {
                check_text(line, j);
                out.percent = true;
                if (body_begin == std::string_view::npos) body_begin = i;
                body_end = i + 1;
                i = j;
                continue;
            }
        }
        if (c == '#' || c == '[' || c == ']' || c == '=' || c == '<' || c == '>')
            fail(i, std::string("unexpected '") + c + "': parameters and expressions are not supported");
        fail(i, std::string("unexpected character '") + c + "'");
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
    std::string_view body = line.substr(body_begin, body_end - body_begin);
    while (!body.empty() && is_blank(body.back())) body.remove_suffix(1);
    out.body = body;
    if (out.words.empty() && out.has_comment && !out.percent && declares_compact(body)) out.compact_words = true;
}

}  // namespace xlate5
