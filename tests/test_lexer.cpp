// SPDX-License-Identifier: GPL-3.0-or-later
// Lexer: G-code syntax in, words out. Every expectation here is written from the G-code
// conventions (RS274/NIST, Marlin host protocol, RepRapFirmware strings), not from lexer output.
#include <doctest/doctest.h>

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <random>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "translators/error.hpp"
#include "translators/inputs/gcode_lexer.hpp"

namespace {
bool contains(const std::string& hay, const std::string& needle) { return hay.find(needle) != std::string::npos; }
}  // namespace

using namespace xlate5;

namespace {

Block lex(std::string_view line) {
    Block b;
    lex_line(line, b);
    return b;
}

struct Expected {
    char letter;
    double value;  // NaN: a flag (no number)
};

void check_words(const Block& b, std::initializer_list<Expected> expected) {
    REQUIRE(b.words().size() == expected.size());
    std::size_t i = 0;
    for (const Expected& e : expected) {
        CAPTURE(i);
        CHECK(b.words()[i].letter == e.letter);
        if (std::isnan(e.value)) {
            CHECK_FALSE(b.words()[i].has_value);
        } else {
            CHECK(b.words()[i].has_value);
            CHECK(b.words()[i].value == e.value);
        }
        ++i;
    }
}

constexpr double kFlag = std::numeric_limits<double>::quiet_NaN();

// Lexes a line that must fail; returns the error. `first_col`..`last_col` (1-based) is the range
// a correct column may point at (the offending word's letter up to the offending character).
LineError lex_error(std::string_view line, std::uint32_t first_col, std::uint32_t last_col, std::string_view mention) {
    Block b;
    try {
        lex_line(line, b);
    } catch (const LineError& e) {
        CAPTURE(std::string(line));
        CAPTURE(std::string(e.what()));
        CHECK(e.column() >= first_col);
        CHECK(e.column() <= last_col);
        CHECK(std::string(e.what()).find(mention) != std::string::npos);
        return e;
    } catch (const std::exception& e) {
        FAIL("expected LineError for '" << std::string(line) << "', got other exception: " << e.what());
    }
    FAIL("expected LineError for '" << std::string(line) << "', lexed without error");
    return LineError(0, "");
}

}  // namespace

TEST_CASE("lexer: a plain move gives letters, values and 1-based columns") {
    const Block b = lex("G1 X10 Y-2.5 E0.25 F1200");
    check_words(b, {{'G', 1}, {'X', 10}, {'Y', -2.5}, {'E', 0.25}, {'F', 1200}});
    CHECK(b.words()[0].column == 1);
    CHECK(b.words()[1].column == 4);
    CHECK(b.words()[2].column == 8);
    CHECK(b.words()[3].column == 14);
    CHECK(b.words()[4].column == 20);
    CHECK(b.body == "G1 X10 Y-2.5 E0.25 F1200");
    CHECK_FALSE(b.has_comment);
    CHECK_FALSE(b.percent);
    CHECK_FALSE(b.text_argument);
}

TEST_CASE("lexer: every number reads as std::from_chars reads it, whatever its length and place in the line") {
    // The lexer reads numbers of up to 19 digits itself and longer ones with from_chars: numbers
    // of 1 to 24 digits, with and without a point and sign, leading zeros, at the end of the line
    // (where the scan stops at the NUL after the lexer's copy) or followed by another word,
    // against from_chars as the reference.
    std::mt19937_64 rng(3);
    int checked = 0;
    for (int i = 0; i < 60000; ++i) {
        const int int_digits = int(rng() % 14), frac_digits = int(rng() % 12);
        std::string text;
        if (rng() % 3 == 0) text += '-';
        for (int k = 0; k < int_digits; ++k) text += char('0' + (k == 0 && rng() % 4 ? 1 + rng() % 9 : rng() % 10));
        if (frac_digits > 0 || rng() % 5 == 0) text += '.';
        for (int k = 0; k < frac_digits; ++k) text += char('0' + rng() % 10);
        const std::string digits = text[0] == '-' ? text.substr(1) : text;
        if (digits.find_first_of("0123456789") == std::string::npos) continue;
        double ref = 0;
        const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), ref, std::chars_format::fixed);
        REQUIRE(r.ec == std::errc{});
        if (text[0] == '-') ref = -ref;
        const std::string tail = rng() % 2 ? "" : (rng() % 2 ? " Y7" : " E0.01230 ; c");
        const std::string line = "G1 X" + text + tail;
        CAPTURE(line);
        if (std::abs(ref) > 1e9) {
            CHECK_THROWS_AS(lex(line), LineError);
            continue;
        }
        const Block b = lex(line);
        REQUIRE(b.words().size() >= 2);
        CHECK(b.words()[1].value == ref);
        CHECK(std::signbit(b.words()[1].value) == std::signbit(ref));
        CHECK(b.words()[1].text == text);
        ++checked;
    }
    CHECK(checked > 30000);
}

TEST_CASE("lexer: at the range limit, with every count of decimals, numbers read as from_chars reads them") {
    // The lexer's own reading takes a number up to 1e9 and 15 significant digits; longer ones
    // and the limit's other side go to from_chars. Both sides of each bound, against it.
    for (const char* text : {"1000000000", "1000000000.0", "1000000000.000000", "1000000000.0000000000", "999999999.999999",
                             "999999999.9999999", "999999999999999", "99999999.99999999", "0.000000000000001",
                             "0.0000000000000000001", "123456789012345", "1234567.89012345", "-1000000000.00000",
                             "00000000000000000001", "0000000000000000000.5"}) {
        const std::string number(text);
        CAPTURE(number);
        const std::string digits = number[0] == '-' ? number.substr(1) : number;
        double ref = 0;
        std::from_chars(digits.data(), digits.data() + digits.size(), ref, std::chars_format::fixed);
        if (number[0] == '-') ref = -ref;
        if (std::abs(ref) > 1e9) {
            lex_error("G1 X" + number, 4, 5, "out of range");
            continue;
        }
        const Block b = lex("G1 X" + number);
        REQUIRE(b.words().size() == 2);
        CHECK(b.words()[1].value == ref);
    }
}

TEST_CASE("lexer: a line is read up to its end only, and its words and body point into it") {
    // The view ends inside a number: the digits after it are not the line's.
    const std::string text = "G1 X12345 Y6";
    const std::string_view line(text.data(), 6);
    const Block b = lex(line);
    check_words(b, {{'G', 1}, {'X', 12}});
    CHECK(b.words()[1].text.data() == text.data() + 4);
    CHECK(b.words()[1].text == "12");
    CHECK(b.body.data() == text.data());
    CHECK(b.body == "G1 X12");
    // A blank, a flag and a sign at the very end.
    check_words(lex("G1 X5 "), {{'G', 1}, {'X', 5}});
    check_words(lex("G28 X"), {{'G', 28}, {'X', kFlag}});
    lex_error("G1 X-", 4, 5, "sign");
}

TEST_CASE("lexer: a line of many words (more than the block had room for) keeps them all in order") {
    Block b;
    lex_line("G1 X1", b);
    std::string line = "G1";
    for (int k = 0; k < 300; ++k) line += " X" + std::to_string(k) + ".5";
    lex_line(line, b);
    REQUIRE(b.words().size() == 301);
    std::uint32_t column = 4;
    for (int k = 0; k < 300; ++k) {
        CAPTURE(k);
        CHECK(b.words()[std::size_t(k) + 1].value == k + 0.5);
        CHECK(b.words()[std::size_t(k) + 1].column == column);
        column += std::uint32_t(std::to_string(k).size() + 4);
    }
    CHECK(b.body == line);
    lex_line("G0 Y2", b);
    check_words(b, {{'G', 0}, {'Y', 2}});
}

TEST_CASE("lexer: ';' comments end the words; the body keeps the comment text") {
    const Block b = lex("G1 X1 ; move Y9 here");
    check_words(b, {{'G', 1}, {'X', 1}});
    CHECK(b.has_comment);
    CHECK(b.body == "G1 X1 ; move Y9 here");

    const Block c = lex(";LAYER:3");
    CHECK(c.words().empty());
    CHECK(c.has_comment);
    CHECK(c.body == ";LAYER:3");
}

TEST_CASE("lexer: '( )' comments mid-line are skipped and the words after them are read") {
    const Block b = lex("G1 X1 (tilt Y7 first) Y2 (end)");
    check_words(b, {{'G', 1}, {'X', 1}, {'Y', 2}});
    CHECK(b.words()[2].column == 23);
    CHECK(b.has_comment);
    CHECK(b.body == "G1 X1 (tilt Y7 first) Y2 (end)");

    const Block c = lex("(only a comment)");
    CHECK(c.words().empty());
    CHECK(c.has_comment);
    CHECK(c.body == "(only a comment)");
}

TEST_CASE("lexer: a leading N line number and a trailing *checksum are not words and not in the body") {
    const Block b = lex("N123 G1 X5*71");
    check_words(b, {{'G', 1}, {'X', 5}});
    CHECK(b.words()[0].column == 6);
    CHECK(b.body == "G1 X5");

    const Block c = lex("N7 M105*36  ");
    check_words(c, {{'M', 105}});
    CHECK(c.body == "M105");

    // A checksum may be followed by blanks and a comment, still outside the body.
    const Block d = lex("N8 G92 E0*99 ; reset");
    check_words(d, {{'G', 92}, {'E', 0}});
    CHECK(d.body.find('*') == std::string_view::npos);
    CHECK(d.body.substr(0, 6) == "G92 E0");
}

TEST_CASE("lexer: letters in any case are upper-cased") {
    const Block b = lex("g1 x10 y-1 e.5");
    check_words(b, {{'G', 1}, {'X', 10}, {'Y', -1}, {'E', 0.5}});
}

TEST_CASE("lexer: words need no spaces between them") {
    // "-.3E+1" also reads as the exponent -3, so this line needs the file's compact declaration
    // (see the next cases); without it the same words come from an E that cannot be an exponent.
    Block b;
    lex_line("; xlate5: compact-words", b);
    lex_line("G1X10Y2Z-.3E+1F600", b);
    check_words(b, {{'G', 1}, {'X', 10}, {'Y', 2}, {'Z', -0.3}, {'E', 1}, {'F', 600}});
    CHECK(b.words()[1].column == 3);
    CHECK(b.words()[2].column == 6);
    CHECK(b.words()[3].column == 8);
    const Block c = lex("G1X10Y2Z-.3E+1.0F600");
    check_words(c, {{'G', 1}, {'X', 10}, {'Y', 2}, {'Z', -0.3}, {'E', 1}, {'F', 600}});
}

TEST_CASE("lexer: a number directly followed by E and an integer is refused unless the file is declared compact") {
    // A CAM program printing 1.5e-05 means 0.000015; compact G-code means X1.5 and a 5 mm retract.
    const LineError e = lex_error("G1 X1.5e-05 Y2", 4, 8, "ambiguous");
    CHECK(e.column() == 8);  // the 'e'
    const std::string why = e.what();
    CHECK(contains(why, "'X1.5e-05'"));
    CHECK(contains(why, "X1.5 e-05"));  // the fix: a blank before a separate E word
    CHECK(contains(why, "without one"));  // or the number without an exponent
    CHECK(contains(why, std::string(kCompactDeclaration)));
    lex_error("G1 X1e308", 4, 6, "ambiguous");    // would be a 308 mm extrusion
    lex_error("G1X10Y2Z-.3E+1F600", 8, 12, "ambiguous");
    lex_error("G1 Y-2.E3", 4, 8, "ambiguous");
    lex_error("G1 F1E3", 4, 6, "ambiguous");       // a feed of 1000, or F1 and 3 mm of filament
    lex_error("G1 A30e+2", 4, 7, "ambiguous");
    // Not ambiguous: an E number with a point (an exponent has none), a blank before E, a
    // command word (no code has an exponent), E not followed by digits.
    check_words(lex("G1 X1E0.5"), {{'G', 1}, {'X', 1}, {'E', 0.5}});
    check_words(lex("G1 X1.5 e-05"), {{'G', 1}, {'X', 1.5}, {'E', -5}});
    check_words(lex("G1E-1F2400"), {{'G', 1}, {'E', -1}, {'F', 2400}});
    check_words(lex("M84 X1E"), {{'M', 84}, {'X', 1}, {'E', kFlag}});
    check_words(lex("G1 X1E-.5"), {{'G', 1}, {'X', 1}, {'E', -0.5}});
}

TEST_CASE("lexer: the compact declaration reads X1.5E-05 as X1.5 and E-05, from its line on") {
    for (const char* declaration : {"; xlate5: compact-words", ";xlate5: compact-words  ", "(XLATE5: Compact-Words)",
                                    "  ( xlate5: compact-words )\r"}) {
        CAPTURE(declaration);
        Block b;
        lex_line("G1 X1 Y2", b);
        CHECK_FALSE(b.compact_words);
        lex_line(declaration, b);
        CHECK(b.compact_words);
        CHECK(b.words().empty());
        lex_line("G1 X1.5E-05", b);
        check_words(b, {{'G', 1}, {'X', 1.5}, {'E', -5}});
        CHECK(b.words()[2].text == "-05");
        lex_line("G1 X1e308", b);  // kept for every later line
        check_words(b, {{'G', 1}, {'X', 1}, {'E', 308}});
    }
    // Only a comment line of its own, with exactly that text, declares it.
    for (const char* not_declaration : {"G1 X1 ; xlate5: compact-words", "; xlate5: compact-words please", "; compact-words",
                                        "(xlate5: compact-words) (more)", "M117 xlate5: compact-words"}) {
        CAPTURE(not_declaration);
        Block b;
        lex_line(not_declaration, b);
        CHECK_FALSE(b.compact_words);
        CHECK_THROWS_AS(lex_line("G1 X1.5E-05", b), LineError);
    }
}

TEST_CASE("lexer: number forms .5, -.309, +3, 5., 007 and a space after the letter") {
    check_words(lex("G1 X.5"), {{'G', 1}, {'X', 0.5}});
    check_words(lex("G1 Y-.309"), {{'G', 1}, {'Y', -0.309}});
    check_words(lex("G1 Z+3"), {{'G', 1}, {'Z', 3}});
    check_words(lex("G1 Z5."), {{'G', 1}, {'Z', 5}});
    check_words(lex("G1 X007"), {{'G', 1}, {'X', 7}});
    const Block b = lex("G1 X 10 Y  -2");  // RS274: blanks inside a word are allowed
    check_words(b, {{'G', 1}, {'X', 10}, {'Y', -2}});
    CHECK(b.words()[1].column == 4);
    CHECK(b.words()[2].column == 9);
    // Largest accepted magnitude.
    check_words(lex("G1 X1000000000"), {{'G', 1}, {'X', 1e9}});
    check_words(lex("G1 X-1000000000"), {{'G', 1}, {'X', -1e9}});
    check_words(lex("G1 X1000000000.00000"), {{'G', 1}, {'X', 1e9}});
    check_words(lex("G1 X999999999.99999"), {{'G', 1}, {'X', 999999999.99999}});
    check_words(lex("G1 X999999999.9999999"), {{'G', 1}, {'X', 999999999.9999999}});  // 16 digits: the slow path
    // Decimal commands.
    check_words(lex("G43.4"), {{'G', 43.4}});
}

TEST_CASE("lexer: CRLF line ends and blank lines") {
    const Block b = lex("G1 X1\r");
    check_words(b, {{'G', 1}, {'X', 1}});
    CHECK(b.body == "G1 X1");

    const Block c = lex("; note\r");
    CHECK(c.body == "; note");

    for (std::string_view blank : {"", "   ", "\t", "\r", "  \t \r"}) {
        CAPTURE(std::string(blank));
        const Block e = lex(blank);
        CHECK(e.words().empty());
        CHECK(e.empty());
        CHECK(e.body.empty());
        CHECK_FALSE(e.has_comment);
    }
}

TEST_CASE("lexer: a 1 MB comment on a line is accepted") {
    std::string line = "G1 X3 ;";
    line.append(std::size_t(1) << 20, 'c');
    const Block b = lex(line);
    check_words(b, {{'G', 1}, {'X', 3}});
    CHECK(b.has_comment);
    CHECK(b.body.size() == line.size());

    std::string paren = "G1 X4 (";
    paren.append(std::size_t(1) << 20, 'p');
    paren += ") Y1";
    check_words(lex(paren), {{'G', 1}, {'X', 4}, {'Y', 1}});
}

TEST_CASE("lexer: a lone '%' is a program delimiter, not an error") {
    const Block b = lex("%");
    CHECK(b.percent);
    CHECK(b.words().empty());
    CHECK(b.body == "%");
    const Block c = lex("  %  ");
    CHECK(c.percent);
    const Block d = lex("% (program start)");
    CHECK(d.percent);
    CHECK(d.words().empty());
}

TEST_CASE("lexer: M117 takes the rest of the line as text; a checksum still ends it") {
    const Block b = lex("M117 Hello world*12");
    check_words(b, {{'M', 117}});
    CHECK(b.text_argument);
    CHECK(b.body == "M117 Hello world");

    // Letters and digits in the text are not words, and a ';' is part of the message.
    const Block c = lex("M117 X10 done; 50%");
    check_words(c, {{'M', 117}});
    CHECK(c.text_argument);
    CHECK(c.body == "M117 X10 done; 50%");

    const Block d = lex("N4 M23 model.gco*80");
    check_words(d, {{'M', 23}});
    CHECK(d.body == "M23 model.gco");
}

TEST_CASE("lexer: reusing a Block resets every flag of the previous line") {
    // lex_line reuses `out`: a line without a text argument must not inherit the flag.
    Block b;
    lex_line("M117 Printing", b);
    REQUIRE(b.text_argument);
    lex_line("G1 X1", b);
    // Every flag of the Block is reset by the next line (text_argument once leaked).
    CHECK_FALSE(b.text_argument);
    CHECK_FALSE(b.has_comment);
    CHECK_FALSE(b.percent);
    check_words(b, {{'G', 1}, {'X', 1}});

    lex_line("%", b);
    REQUIRE(b.percent);
    lex_line("; c", b);
    CHECK_FALSE(b.percent);
    CHECK(b.has_comment);
    lex_line("G28", b);
    CHECK_FALSE(b.has_comment);
}

TEST_CASE("lexer: RepRapFirmware quoted strings, with \"\" as an embedded quote") {
    const Block b = lex(R"(M291 P"hi ""there""" S1)");
    check_words(b, {{'M', 291}, {'P', kFlag}, {'S', 1}});
    CHECK(b.words()[2].column == 22);
    // Letters, digits and ';' inside the string are not words and not a comment.
    const Block c = lex(R"(M98 P"config; X1 Y2.g")");
    check_words(c, {{'M', 98}, {'P', kFlag}});
    CHECK_FALSE(c.has_comment);
}

TEST_CASE("lexer: valueless flags such as G28 X and M84 E") {
    const Block a = lex("G28 X");
    check_words(a, {{'G', 28}, {'X', kFlag}});
    CHECK(std::isnan(a.words()[1].value));
    CHECK(a.words()[1].column == 5);
    check_words(lex("M84 E"), {{'M', 84}, {'E', kFlag}});
    check_words(lex("G28 X ; home x"), {{'G', 28}, {'X', kFlag}});
    check_words(lex("G28 X0 Y0"), {{'G', 28}, {'X', 0}, {'Y', 0}});
}

TEST_CASE("lexer: several valueless flags in a row (G28 X Y)") {
    // A flag followed by a blank and the next word ("X Y") is two flags, not the run-on text
    // "X Y": Marlin's own "G28 X Y" and "M84 X Y E" (this once failed).
    Block b;
    CHECK_NOTHROW(lex_line("G28 X Y", b));
    if (b.words().size() == 3) {
        check_words(b, {{'G', 28}, {'X', kFlag}, {'Y', kFlag}});
        CHECK(b.words()[1].column == 5);
        CHECK(b.words()[2].column == 7);
    }
    Block c;
    CHECK_NOTHROW(lex_line("M84 X Y E", c));
    if (c.words().size() == 4) check_words(c, {{'M', 84}, {'X', kFlag}, {'Y', kFlag}, {'E', kFlag}});
}

// ---- errors ------------------------------------------------------------------------------

TEST_CASE("lexer error: G, M, T (and N) need a number") {
    lex_error("G X1", 1, 1, "G");
    lex_error("G1 X1 M", 7, 7, "M");
    lex_error("T", 1, 1, "T");
    const LineError e = lex_error("G X1", 1, 1, "number");
    CHECK(e.column() == 1);
}

TEST_CASE("lexer error: G, M and T numbers are codes below 100000") {
    // G429496730.6 is code 4294967306 tenths, which wrapped around a 32-bit int onto G1.
    lex_error("G429496730.6 X105", 1, 1, "below 100000");
    lex_error("G1 M1000000", 4, 4, "below 100000");
    lex_error("T100000", 1, 1, "code");
    lex_error("G-100000", 1, 1, "code");
    check_words(lex("G99999.9 M99999 T99999"), {{'G', 99999.9}, {'M', 99999}, {'T', 99999}});
    check_words(lex("G1 X100000 N100000"), {{'G', 1}, {'X', 100000}, {'N', 100000}});  // values, not codes
}

TEST_CASE("lexer error: a sign without digits") {
    lex_error("G1 X-", 4, 5, "sign");
    lex_error("G1 X+ Y1", 4, 5, "sign");
    lex_error("G1 X-.", 4, 5, "number");
}

TEST_CASE("lexer error: NaN and infinity are not numbers") {
    lex_error("G1 Xnan", 4, 5, "finite");
    lex_error("G1 XINF", 4, 5, "finite");
    lex_error("G1 X-inf", 4, 5, "finite");
    lex_error("G1 X NaN", 4, 6, "finite");
}

TEST_CASE("lexer error: a number beyond 1e9 is out of range") {
    lex_error("G1 X12345678901", 4, 5, "out of range");
    lex_error("G1 Y-1000000000.5", 4, 5, "out of range");
    // Just past the limit, at every count of decimals the range check sees before dividing.
    lex_error("G1 X1000000001", 4, 5, "out of range");
    lex_error("G1 X1000000000.1", 4, 5, "out of range");
    lex_error("G1 X1000000000.01", 4, 5, "out of range");
    lex_error("G1 X1000000000.001", 4, 5, "out of range");
    lex_error("G1 X1000000000.0001", 4, 5, "out of range");
    lex_error("G1 X1000000000.00001", 4, 5, "out of range");
    lex_error("G1 X-1000000000.00001", 4, 5, "out of range");
}

TEST_CASE("lexer error: bytes that are not text") {
    using namespace std::string_view_literals;
    const LineError nul = lex_error("G1 X1\0Y2"sv, 6, 6, "0x00");
    CHECK(nul.column() == 6);
    lex_error("G1\x01X1"sv, 3, 3, "0x01");
    lex_error("G1 X1\x7F"sv, 6, 6, "0x7F");
    // A NUL inside a comment is still not text.
    lex_error("; a\0b"sv, 4, 4, "non-text");
    // A '\r' that is not the line end.
    lex_error("G1\rX1"sv, 3, 3, "non-text");
}

TEST_CASE("lexer: non-ASCII is an error outside a comment and allowed inside one") {
    lex_error("G1 X1 \xC3\xA9", 7, 7, "non-ASCII");
    lex_error("G1 X\xC2\xB5", 5, 5, "non-ASCII");
    const Block b = lex("G1 X1 ; temp\xC3\xA9rature 200\xC2\xB0");
    check_words(b, {{'G', 1}, {'X', 1}});
    const Block c = lex("G1 (\xC3\xBC) X2");
    check_words(c, {{'G', 1}, {'X', 2}});
}

TEST_CASE("lexer error: an unclosed '(' comment") {
    const LineError e = lex_error("G1 X1 (no end", 7, 7, "not closed");
    CHECK(e.column() == 7);
    lex_error("(", 1, 1, "(");
}

TEST_CASE("lexer error: parameters and expressions '#', '[' are not supported") {
    lex_error("G1 X#1", 5, 5, "#");
    lex_error("#1 = 5", 1, 1, "#");
    lex_error("G1 X[1+2]", 5, 5, "[");
}

TEST_CASE("lexer error: text after the checksum") {
    lex_error("N3 G1 X1*12 Y2", 13, 13, "checksum");
    lex_error("G1 X1*", 6, 6, "checksum");
}

TEST_CASE("lexer: the words of the bulk of a program read as the general reading reads them") {
    // The lexer reads a letter directly followed by a short number in a loop of its own; a blank
    // after the letter ("X 90.000", which RS274 allows) takes the general reading instead. Random
    // lines of words in many forms (signs, points, leading zeros, long numbers, flags, lower case,
    // codes out of range, exponent-like E, no separators, tabs, comments), read both ways: the same
    // words, values to the bit, text and letters, or an error both ways.
    std::mt19937_64 rng(15);
    const std::string letters = "GXYZABCEFIJKMTNSPRHxyzegmt";
    auto number = [&] {
        std::string t;
        switch (rng() % 8) {
            case 0: t += '-'; break;
            case 1: if (rng() % 4 == 0) t += '+'; break;
            default: break;
        }
        const int int_digits = int(rng() % 12 == 0 ? rng() % 13 : rng() % 4), frac_digits = int(rng() % 10 == 0 ? rng() % 12 : rng() % 7);
        for (int k = 0; k < int_digits; ++k) t += char('0' + rng() % 10);
        if (frac_digits > 0 || rng() % 8 == 0) t += '.';
        for (int k = 0; k < frac_digits; ++k) t += char('0' + rng() % 10);
        if (rng() % 40 == 0) t = "";  // a flag
        return t;
    };
    int lines = 0, fast_words = 0, errors = 0;
    for (int n = 0; n < 40000; ++n) {
        std::string line, general;
        const int words = 1 + int(rng() % 9);
        for (int w = 0; w < words; ++w) {
            const char* separators[] = {" ", " ", " ", " ", "", "\t", "  "};
            const std::string sep = w == 0 ? (rng() % 10 == 0 ? " " : "") : separators[rng() % 7];
            const char letter = letters[rng() % letters.size()];
            std::string num = number();
            if (rng() % 30 == 0 && num.find_first_of("0123456789") != std::string::npos) num += (rng() % 2 ? "e-05" : "E3");
            line += sep + letter + num;
            general += sep + letter;
            // The general reading, forced by a blank; after a separator only, so that an E right
            // after a number stays as it is (it may be an exponent) and a flag stays a flag.
            if ((w == 0 || !sep.empty()) && !num.empty()) general += ' ';
            general += num;
        }
        if (rng() % 10 == 0) {
            line += " ; note";
            general += " ; note";
        }
        CAPTURE(line);
        CAPTURE(general);
        Block a, b;
        bool a_ok = true, b_ok = true;
        try {
            lex_line(line, a);
        } catch (const LineError&) {
            a_ok = false;
        }
        try {
            lex_line(general, b);
        } catch (const LineError&) {
            b_ok = false;
        }
        REQUIRE(a_ok == b_ok);
        if (!a_ok) {
            ++errors;
            continue;
        }
        ++lines;
        REQUIRE(a.words().size() == b.words().size());
        CHECK(a.letters == b.letters);
        for (std::size_t k = 0; k < a.words().size(); ++k) {
            const Word& x = a.words()[k];
            const Word& y = b.words()[k];
            CAPTURE(k);
            CHECK(x.letter == y.letter);
            CHECK(x.has_value == y.has_value);
            CHECK(x.text == y.text);
            if (x.has_value) {
                CHECK(x.value == y.value);
                CHECK(std::signbit(x.value) == std::signbit(y.value));
            }
            REQUIRE(x.column >= 1);
            CHECK(std::toupper(static_cast<unsigned char>(line[x.column - 1])) == x.letter);
            if (x.has_value && x.column < line.size() && line[x.column] != ' ') ++fast_words;
        }
    }
    CHECK(lines > 10000);
    CHECK(errors > 1000);
    CHECK(fast_words > 50000);
}

TEST_CASE("lexer: a line read in place (a NUL after it) reads as its copy reads") {
    // The look-back keeps each line's text (a std::string, a NUL after it) and the lexer reads it
    // there instead of copying it: random lines of words, comments, text arguments, checksums,
    // '\r' ends and NULs inside, read both ways: the same block, or the same error.
    std::mt19937_64 rng(34);
    const std::vector<std::string> parts = {"G1", " X1.5", "Y-2", " E0.05", " F1200", "A", " B30.25", "M117 hello", " ; note",
                                            "(c)", "*12", "N5 ", "\r", std::string(1, '\0'), " ", "x.5", "T0", "%", "E", "1e3"};
    int read = 0, errors = 0;
    for (int n = 0; n < 20000; ++n) {
        std::string line;
        for (int k = 1 + int(rng() % 6); k > 0; --k) line += parts[rng() % parts.size()];
        CAPTURE(line);
        Block copied, in_place;
        std::string copied_error, in_place_error;
        try {
            lex_line(line, copied);
        } catch (const LineError& e) {
            copied_error = std::to_string(e.column()) + e.what();
        }
        try {
            lex_line(line, in_place, true);
        } catch (const LineError& e) {
            in_place_error = std::to_string(e.column()) + e.what();
        }
        REQUIRE(copied_error == in_place_error);
        if (!copied_error.empty()) {
            ++errors;
            continue;
        }
        ++read;
        CHECK(copied.body == in_place.body);
        CHECK(copied.letters == in_place.letters);
        CHECK(copied.has_comment == in_place.has_comment);
        CHECK(copied.percent == in_place.percent);
        CHECK(copied.text_argument == in_place.text_argument);
        REQUIRE(copied.words().size() == in_place.words().size());
        for (std::size_t k = 0; k < copied.words().size(); ++k) {
            const Word& x = copied.words()[k];
            const Word& y = in_place.words()[k];
            CHECK(x.letter == y.letter);
            CHECK(x.has_value == y.has_value);
            CHECK(x.text == y.text);
            CHECK(x.column == y.column);
            if (x.has_value) CHECK(std::memcmp(&x.value, &y.value, sizeof x.value) == 0);
        }
    }
    CHECK(read > 2000);
    CHECK(errors > 2000);
}
