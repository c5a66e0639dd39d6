// SPDX-License-Identifier: GPL-3.0-or-later
// Line reader and output sink: chunk boundaries, long lines, atomic output; number formatting.
#include <doctest/doctest.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <unistd.h>
#include <vector>

#include "translators/error.hpp"
#include "translators/number.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/stream.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;
namespace fs = std::filesystem;

namespace {

// A pipe carrying `text`, read back through LineReader.
std::vector<std::string> read_all(const std::string& text, std::size_t max_line = 64u << 20) {
    const fs::path p = fs::temp_directory_path() / ("xlate5-stream-" + std::to_string(::getpid()));
    {
        std::ofstream o(p, std::ios::binary);
        o << text;
    }
    FILE* f = std::fopen(p.c_str(), "rb");
    REQUIRE(f);
    LineReader r(::fileno(f), p.string(), max_line);
    std::vector<std::string> lines;
    std::string_view line;
    try {
        while (r.next(line)) lines.emplace_back(line);
    } catch (...) {
        std::fclose(f);
        fs::remove(p);
        throw;
    }
    CHECK(r.line_number() == lines.size());
    std::fclose(f);
    fs::remove(p);
    return lines;
}

}  // namespace

TEST_CASE("lines across chunk boundaries, with and without a final newline") {
    std::string text;
    std::vector<std::string> expect;
    std::mt19937 rng(3);
    for (int i = 0; i < 60000; ++i) {
        std::string l(std::size_t(rng() % 90), 'x');
        l += std::to_string(i);
        expect.push_back(l);
        text += l + "\n";
    }
    CHECK(read_all(text) == expect);
    text.pop_back();
    CHECK(read_all(text) == expect);
    CHECK(read_all("").empty());
    CHECK(read_all("\n\n") == std::vector<std::string>{"", ""});
}

TEST_CASE("a line longer than the chunk is read whole; one past the limit is an input error") {
    const std::string big(3u << 20, ';');
    const auto lines = read_all("G1 X1\n" + big + "\nG1 X2\n");
    REQUIRE(lines.size() == 3);
    CHECK(lines[1].size() == big.size());
    CHECK_THROWS_AS(read_all("G1\n" + big + "\n", 1u << 20), InputError);
}

TEST_CASE("an output file appears only on commit; without it nothing is left behind") {
    const fs::path dir = fs::temp_directory_path() / ("xlate5-sink-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const fs::path out = dir / "out.gcode";
    {
        std::ofstream o(out);
        o << "old\n";
    }
    {
        OutputSink s(out.string());
        s.write("new partial\n");
        // destroyed without commit: as after an error
    }
    CHECK(std::distance(fs::directory_iterator(dir), fs::directory_iterator()) == 1);
    std::ifstream in(out);
    std::string content((std::istreambuf_iterator<char>(in)), {});
    CHECK(content == "old\n");
    {
        OutputSink s(out.string());
        s.write("new\n");
        s.commit();
    }
    std::ifstream in2(out);
    std::string content2((std::istreambuf_iterator<char>(in2)), {});
    CHECK(content2 == "new\n");
    fs::remove_all(dir);
}

TEST_CASE("the stream's counts of lines and bytes out are those of the output written") {
    // A split rw2 wall (pieces of different lengths, lines of every length), read back from the
    // file the sink wrote: the counts must match it exactly, across the sink's blocks.
    const Machine m = load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml");
    const Kinematics k(m);
    const fs::path dir = fs::temp_directory_path() / ("xlate5-counts-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const fs::path in = dir / "in.gcode", out = dir / "out.gcode";
    {
        std::ofstream o(in);
        o << "G21\nG90\nM83\n";
        for (int i = 0; i < 20000; ++i) {
            const double t = i * 0.01;
            o << "G1 X" << 60 + 30 * std::cos(t) << " Y" << 60 + 30 * std::sin(t) << " Z" << 1 + 0.0002 * i << " A"
              << std::fmod(t * 57.3, 300.0) - 150.0 << " B" << 20 * std::sin(t * 0.1) << " E0.0123" << (i % 7 ? "" : " ; note") << "\n";
        }
    }
    FILE* f = std::fopen(in.c_str(), "rb");
    REQUIRE(f);
    LineReader reader(::fileno(f), in.string());
    Translator translator(k, {});
    StreamStats stats;
    {
        OutputSink sink(out.string());
        stats = translate_stream(reader, translator, sink);
        sink.commit();
    }
    std::fclose(f);
    std::ifstream o(out, std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(o)), {});
    CHECK(stats.lines_in == 20003);
    CHECK(stats.bytes_out == text.size());
    CHECK(stats.lines_out == std::uint64_t(std::count(text.begin(), text.end(), '\n')));
    CHECK(stats.lines_out > 20003);  // the 300-degree turns were split
    fs::remove_all(dir);
}

TEST_CASE("append_fixed prints what std::to_chars prints at the same precision") {
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> U(-1000, 1000);
    int checked = 0;
    for (int i = 0; i < 200000; ++i) {
        const double v = (i % 3 == 0) ? U(rng) : (i % 3 == 1 ? U(rng) * 1e-3 : std::round(U(rng) * 100) / 100);
        for (int d : {0, 1, 3, 4, 6}) {
            char buf[64];
            auto r = std::to_chars(buf, buf + 64, v, std::chars_format::fixed, d);
            std::string ref(buf, r.ptr);
            // Reference: drop trailing fraction zeros and the point, and "-0" -> "0".
            if (ref.find('.') != std::string::npos) {
                while (ref.back() == '0') ref.pop_back();
                if (ref.back() == '.') ref.pop_back();
            }
            if (ref == "-0") ref = "0";
            std::string mine;
            append_fixed(mine, v, d);
            // Exact ties are rounded half away from zero here, to even by to_chars: allow only those.
            if (mine != ref) {
                const double scaled = v * std::pow(10.0, d);
                CHECK(std::abs(std::abs(scaled - std::trunc(scaled)) - 0.5) < 1e-6);
            }
            ++checked;
        }
    }
    CHECK(checked == 1000000);
}

TEST_CASE("write_units writes the integer's digits with the point placed and trailing fraction zeros dropped") {
    // Reference: the integer's decimal text from std::to_string, the point inserted by hand.
    auto reference = [](long long units, int d) {
        const bool negative = units < 0;
        std::string digits = std::to_string(units);
        if (negative) digits.erase(0, 1);
        if (d > 0) {
            if (digits.size() <= std::size_t(d)) digits = std::string(std::size_t(d) + 1 - digits.size(), '0') + digits;
            const std::size_t point = digits.size() - std::size_t(d);
            digits = digits.substr(0, point) + "." + digits.substr(point);
            while (digits.back() == '0') digits.pop_back();
            if (digits.back() == '.') digits.pop_back();
        }
        if (digits == "0") return digits;
        return (negative ? "-" : "") + digits;
    };
    std::mt19937_64 rng(11);
    int checked = 0;
    for (int d = 0; d <= 12; ++d) {
        std::vector<long long> values = {0, 1, -1, 5, 10, 100, 1000, 1001, 999999999, 1000000000, -1000000000,
                                         std::numeric_limits<long long>::max(), std::numeric_limits<long long>::min(),
                                         std::numeric_limits<long long>::max() / 10 * 10, 9000000000000000000ll};
        for (int i = 0; i < 20000; ++i) {
            // Every size of number: random digits, a random count of trailing zeros, either sign.
            long long v = (long long)(rng() >> (1 + rng() % 63));
            for (int z = int(rng() % 6); z > 0 && v < std::numeric_limits<long long>::max() / 10; --z) v *= 10;
            values.push_back(rng() % 2 ? -v : v);
        }
        for (const long long v : values) {
            char buf[kUnitsChars + 8];
            const std::string mine(buf, write_units(buf, v, d));
            CHECK_MESSAGE(mine == reference(v, d), v << " at " << d << " decimals");
            std::string appended = "x";
            append_units(appended, v, d);
            CHECK(appended == "x" + mine);
            ++checked;
        }
    }
    CHECK(checked > 250000);
}

TEST_CASE("write_units below a million units, its table paths, writes what the general path writes: every value") {
    // Three decimals below 1000 in magnitude are written inline from two tables; at any count of
    // decimals an integer part below a million is two table entries. Every value of that range
    // and a little past it, against the digit-by-digit text built here.
    auto reference = [](long long units, int d) {
        std::string digits = std::to_string(units < 0 ? -units : units);
        if (d > 0) {
            if (digits.size() <= std::size_t(d)) digits.insert(0, std::size_t(d) + 1 - digits.size(), '0');
            digits.insert(digits.size() - std::size_t(d), 1, '.');
            while (digits.back() == '0') digits.pop_back();
            if (digits.back() == '.') digits.pop_back();
        }
        return (units < 0 && digits != "0" ? "-" : "") + digits;
    };
    for (int d : {0, 1, 3, 4}) {
        bool all = true;
        for (long long v = -1000100; v <= 1000100 && all; ++v) {
            char buf[kUnitsChars];
            all = std::string(buf, write_units(buf, v, d)) == reference(v, d);
            if (!all) CHECK_MESSAGE(false, v << " at " << d << " decimals: " << std::string(buf, write_units(buf, v, d)));
        }
        CHECK(all);
    }
}

TEST_CASE("to_units' branch-free rounding is the C library's llround, and write_units' one-decimal case the general path's, bit for bit") {
    // Half away from zero, exactly: llround. (Adding 0.5 and truncating, as this rounding was
    // first written, gives 1 for 0.5 - 2^-54: the sum rounds up.)
    auto plain = [](double scaled) { return std::llround(scaled); };
    std::mt19937_64 rng(15);
    std::vector<double> values = {0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 0.49999999999999994, -0.49999999999999994,
                                  4503599627370495.5, -4503599627370495.5, 999999999999999.0, -999999999999999.0,
                                  std::numeric_limits<double>::denorm_min(), -std::numeric_limits<double>::denorm_min()};
    // Every half from -0.5 to 4096.5 and at each power of two up to 2^49, with the doubles just
    // either side of it: where an added half can carry into the next binade.
    for (int p = 0; p <= 49; ++p) {
        for (const double n : {std::ldexp(1.0, p) - 1.0, std::ldexp(1.0, p)}) {
            const double half = n + 0.5;
            for (const double v : {half, std::nextafter(half, 0.0), std::nextafter(half, 1e300), std::nextafter(std::nextafter(half, 0.0), 0.0)}) {
                values.push_back(v);
                values.push_back(-v);
            }
        }
    }
    for (int n = -1; n <= 4096; ++n) {
        const double half = double(n) + 0.5;
        for (const double v : {half, std::nextafter(half, -1e300), std::nextafter(half, 1e300)}) values.push_back(v);
    }
    for (int i = 0; i < 1000000; ++i) {
        const int kind = int(rng() % 4);
        double v;
        if (kind == 0) v = std::ldexp(double(rng() >> 11), -int(rng() % 60));     // any magnitude below 1e15
        else if (kind == 1) v = double(static_cast<long long>(rng() % 2000000001) - 1000000000) + 0.5;  // exact ties
        else if (kind == 2) v = std::nextafter(double(static_cast<long long>(rng() % 2000001) - 1000000) + 0.5, rng() % 2 ? 1e300 : -1e300);
        else v = (double(rng() % 2000000001) - 1e9) / 1e3;
        if (std::abs(v) < 1e15) values.push_back(rng() % 2 ? -v : v);
    }
    bool all = true;
    for (const double v : values) {
        if (round_half_away(v) != plain(v)) {
            all = false;
            CHECK_MESSAGE(false, v);
        }
    }
    CHECK(all);
    // write_units at one decimal below 10 000 000 units (inline) against write_units_general; the
    // range up to 1000100 is checked value by value above.
    std::vector<long long> units = {9999999, -9999999, 10000000, -10000000, 10000001, 9999990, 1000000, 999999, 10, -10, 0};
    for (int i = 0; i < 1000000; ++i) units.push_back(static_cast<long long>(rng() % 20000400) - 10000200);
    all = true;
    for (const long long u : units) {
        char a[kUnitsChars], b[kUnitsChars];
        const std::string mine(a, write_units(a, u, 1)), general(b, write_units_general(b, u, 1));
        if (mine != general) {
            all = false;
            CHECK_MESSAGE(false, u << ": " << mine << " vs " << general);
        }
    }
    CHECK(all);
}

TEST_CASE("a number that is not finite or beyond 1e9 is never written: UnwritableNumber, and nothing appended") {
    // std::to_chars fails for |v| >~ 1e61 at 3 decimals in 64 bytes; its buffer must not be written.
    for (const double v : {1e61, -1e200, 1e300, 1e9 * (1 + 1e-15), -2e9, 1e12, std::numeric_limits<double>::infinity(),
                           -std::numeric_limits<double>::infinity(), std::numeric_limits<double>::quiet_NaN()}) {
        CAPTURE(v);
        for (int d : {0, 3, 5, 12}) {
            std::string out = "G1 X";
            CHECK_THROWS_AS(append_fixed(out, v, d), UnwritableNumber);
            CHECK(out == "G1 X");
        }
        std::string out = "G1 E";
        CHECK_THROWS_AS(append_shortest(out, v), UnwritableNumber);
        CHECK(out == "G1 E");
        long long units = 0;
        CHECK_FALSE(to_units(v, 3, units));
    }
    // A LineError, so the translator names the input line.
    try {
        std::string out;
        append_fixed(out, 1e200, 3);
        FAIL("no error");
    } catch (const LineError& e) {
        CHECK(std::string(e.what()).find("1e+200") != std::string::npos);
    }
    // The bound itself is written, and so is a tiny value.
    std::string out;
    append_fixed(out, 1e9, 3);
    out += ' ';
    append_fixed(out, -1e9, 12);
    out += ' ';
    append_shortest(out, -1e9);
    out += ' ';
    append_shortest(out, 1e-300);
    CHECK(out == "1000000000 -1000000000 -1000000000 0");
}

TEST_CASE("count_newlines counts what the memchr path counts: any length, any density, past the byte counters' 255 steps") {
    std::mt19937 rng(15);
    for (int round = 0; round < 3000; ++round) {
        const std::size_t size = round < 100 ? std::size_t(round) : std::size_t(rng() % (round % 10 == 0 ? 20000 : 300));
        const unsigned density = 1 + rng() % 200;  // one byte in `density` is a line end
        std::string text(size, 'x');
        for (char& c : text) c = rng() % density == 0 ? '\n' : char(rng() % 256);
        if (round % 7 == 0) std::fill(text.begin(), text.end(), '\n');  // every byte: counters at their fullest
        const std::size_t skip = size > 0 ? rng() % std::min<std::size_t>(size, 16) : 0;  // unaligned starts
        const std::string_view view = std::string_view(text).substr(skip);
        REQUIRE(count_newlines(view) == count_newlines_memchr(view));
        REQUIRE(count_newlines(view) == std::uint64_t(std::count(view.begin(), view.end(), '\n')));
    }
}
