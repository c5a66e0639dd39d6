// SPDX-License-Identifier: GPL-3.0-or-later
// Benchmark (not a test): the floor under bench_translate. A file of angle-form moves (G43.4: tip
// plus rotary angles, as bench_translate writes for rw2) goes through the project's own lexer,
// position solve and number writer, and nothing else: no command reading, interpreter, planner,
// motion stage, look-back, limits, feed or splitting, and no checks. Reports input lines per CPU
// second of the loop; what the stages in between cost is the difference from bench_translate's
// unsplit figure on the same file.
//   bench_floor FILE [machine=rw2]
// The output is built in memory and thrown away (its size is printed, so it is not optimised out).
#include <cstdio>
#include <ctime>
#include <string>
#include <vector>

#include "translators/error.hpp"
#include "translators/inputs/gcode_lexer.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/number.hpp"

namespace {

double cpu_seconds() {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: bench_floor FILE [machine]\n");
        return 2;
    }
    const xlate5::Machine m = xlate5::load_machine(argc > 2 ? argv[2] : "rw2");
    if (m.start_mode != xlate5::OrientationMode::Angles) {
        std::fprintf(stderr, "bench_floor: %s starts in the vector form; the floor reads angle-form files only\n", m.name.c_str());
        return 2;
    }
    const xlate5::Kinematics kin(m);
    std::string text;
    if (FILE* f = std::fopen(argv[1], "rb")) {
        char buf[1 << 16];
        std::size_t got = 0;
        while ((got = std::fread(buf, 1, sizeof buf, f)) > 0) text.append(buf, got);
        std::fclose(f);
    } else {
        std::perror(argv[1]);
        return 2;
    }

    const std::size_t n = m.joints.size();
    std::vector<double> q(n, 0.0);
    for (std::size_t j = 0; j < n; ++j) q[j] = m.joints[j].home;
    Eigen::Vector3d tip(0, 0, 0);
    std::string out;
    out.reserve(1 << 20);
    std::size_t out_bytes = 0;
    long lines = 0;
    xlate5::Block block;
    const double start = cpu_seconds();
    std::size_t at = 0;
    while (at < text.size()) {
        std::size_t end = text.find('\n', at);
        if (end == std::string::npos) end = text.size();
        const std::string_view line(text.data() + at, end - at);
        at = end + 1;
        ++lines;
        try {
            xlate5::lex_line(line, block);
        } catch (const xlate5::LineError&) {
            continue;
        }
        if (block.words().empty() || block.words()[0].letter != 'G' || block.words()[0].value != 1) {
            out.append(line);
            out += '\n';
            continue;
        }
        std::string_view e;
        for (const auto& w : block.words()) {
            if (w.letter >= 'X' && w.letter <= 'Z') tip[w.letter - 'X'] = w.value;
            else if (w.letter == 'E') e = w.text;
            else
                for (std::size_t j = 0; j < n; ++j)
                    if (m.joints[j].rotary && m.joints[j].name == w.letter) q[j] = w.value;
        }
        kin.solve_position(tip, q);
        char words[8 * (2 + xlate5::kUnitsChars) + 4];
        char* p = words;
        *p++ = 'G';
        *p++ = '1';
        for (std::size_t j = 0; j < n; ++j) {
            const int d = m.joints[j].rotary ? m.dialect.rotary_decimals : m.dialect.linear_decimals;
            long long units = 0;
            if (!xlate5::to_units(q[j], d, units)) continue;
            *p++ = ' ';
            *p++ = m.joints[j].output;
            p = xlate5::write_units(p, units, d);
        }
        out.append(words, p);
        if (!e.empty()) {
            out += " E";
            out.append(e);
        }
        out += '\n';
        if (out.size() > (1u << 20) - 256) {
            out_bytes += out.size();
            out.clear();
        }
    }
    const double cpu = cpu_seconds() - start;
    out_bytes += out.size();
    std::printf("floor: %ld lines, %.3f s CPU, %.2f M lines/s, %zu bytes out\n", lines, cpu, double(lines) / cpu / 1e6, out_bytes);
    return 0;
}
