// SPDX-License-Identifier: GPL-3.0-or-later
// Keep-out throughput: a sliced tube (layers of short G1 moves around an item at its centre,
// the ADD_IN team's figure-1 part, 2015; their MATLAB took about 45 s for 30,000
// moves) through the whole forward pipeline with R computed by the keep-out stage.
//   bench_keep_out [MOVES] [PER_LAYER]     (default 30000 moves, 300 per layer)
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "translators/pipeline/keep_out.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/translator.hpp"

using namespace xlate5;

int main(int argc, char** argv) {
    const long moves = argc > 1 ? std::atol(argv[1]) : 30000;
    const long per_layer = argc > 2 ? std::atol(argv[2]) : 300;
    if (moves < 1 || moves > 100000000 || per_layer < 3 || per_layer > 1000000) {
        std::fprintf(stderr, "usage: bench_keep_out [MOVES 1..1e8] [PER_LAYER 3..1e6]\n");
        return 2;
    }
    std::vector<std::string> lines{"G90", "M83", "G28", "G0 Z5 F3000", "G0 X120 Y100"};
    char buf[128];
    for (long i = 0; i < moves; ++i) {
        if (i % per_layer == 0) std::snprintf(buf, sizeof buf, "G0 Z%.3f", 0.2 * double(i / per_layer + 1)), lines.emplace_back(buf);
        const double a = 2 * 3.14159265358979323846 * double(i % per_layer + 1) / double(per_layer);
        std::snprintf(buf, sizeof buf, "G1 X%.4f Y%.4f E0.02 F1800", 100 + 20 * std::cos(a), 100 + 20 * std::sin(a));
        lines.emplace_back(buf);
    }
    const Machine m = load_machine("addin4");
    const Kinematics k(m);
    const KeepOutItems items = parse_keep_out("100, 100, 0\n", "items.csv");
    TranslatorOptions o;
    o.keep_out = &items;
    Translator t(k, o);
    t.set_lookback(Translator::kDefaultLookback);
    std::string out;
    const auto start = std::chrono::steady_clock::now();
    std::uint64_t n = 0;
    for (const auto& l : lines) t.feed(l, ++n, out);
    t.finish(out);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::size_t out_lines = 0;
    for (char c : out) out_lines += c == '\n';
    std::printf("%ld printing moves (%zu lines in, %zu out) in %.3f s: %.0f lines/s\n", moves, lines.size(), out_lines, s,
                double(lines.size()) / s);
    return 0;
}
