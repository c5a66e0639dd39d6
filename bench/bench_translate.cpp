// SPDX-License-Identifier: GPL-3.0-or-later
// Benchmark (not a test): translate a large generated 5-axis file and report input lines/s,
// MB/s, lines out per line in and peak memory. Run it at two sizes to see that memory does not
// grow with the file; with and without splitting to see what the motion stage costs. Wall time
// and the process's CPU time are both given: on a shared machine the CPU figure is the steadier.
//   bench_translate [lines=1000000] [machine=rw2|pentarod|...] [tolerance mm, 0 = no splitting] [keep=FILE]
// With a fourth argument the generated input is written to FILE and left there (for bench_floor,
// or to run xlate5 itself on it); otherwise it is a temporary file, removed at the end.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fcntl.h>
#include <string>
#include <ctime>
#include <sys/resource.h>
#include <unistd.h>

#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/stream.hpp"
#include "translators/pipeline/translator.hpp"

namespace {

// A helical wall that tilts and turns: every line changes the tip and the orientation, in the
// machine's start mode (angles for G43.4 machines, a tool vector for G43.5 ones).
void generate(const std::string& path, long lines, const xlate5::Machine& m) {
    FILE* f = std::fopen(path.c_str(), "w");
    if (!f) std::exit(2);
    std::fprintf(f, "; xlate5 benchmark input, %ld lines\nG21\nG90\nM83\nG28\n", lines);
    const bool vector = m.start_mode == xlate5::OrientationMode::Vector;
    char r1 = 0, r2 = 0;
    for (const auto& j : m.joints)
        if (j.rotary) (r1 ? r2 : r1) = j.name;
    for (long i = 0; i < lines; ++i) {
        const double t = double(i) * 0.01;
        const double x = 60 + 30 * std::cos(t), y = 60 + 30 * std::sin(t), z = 1 + 0.0002 * double(i % 400000);
        const double tilt = 20 * std::sin(t * 0.1), az = std::fmod(t * 57.29577951308232, 300.0) - 150.0;
        if (vector) {
            const double a = tilt * 0.017453292519943295, c = az * 0.017453292519943295;
            std::fprintf(f, "G1 X%.3f Y%.3f Z%.3f I%.6f J%.6f K%.6f E%.5f F1800\n", x - 60, y - 60, z, std::sin(a) * std::sin(c),
                         std::sin(a) * std::cos(c), std::cos(a), 0.0123);
        } else if (r2) {
            std::fprintf(f, "G1 X%.3f Y%.3f Z%.3f %c%.3f %c%.3f E%.5f\n", x, y, z, r1, az, r2, tilt, 0.0123);
        } else {
            std::fprintf(f, "G1 X%.3f Y%.3f Z%.3f E%.5f\n", x, y, z, 0.0123);
        }
    }
    std::fclose(f);
}

}  // namespace

int main(int argc, char** argv) {
    const long lines = argc > 1 ? std::atol(argv[1]) : 1000000;
    const std::string machine = argc > 2 ? argv[2] : "rw2";
    xlate5::Machine m = xlate5::load_machine(machine);
    if (argc > 3) {
        const double tol = std::atof(argv[3]);
        if (tol > 0) m.motion.tolerance = tol;
        else m.motion.segment = false;
    }
    const xlate5::Kinematics k(m);
    const bool keep = argc > 4;
    const std::string path = keep ? std::string(argv[4]) : "/tmp/xlate5-bench-" + std::to_string(::getpid()) + ".gcode";
    generate(path, lines, m);

    const int fd = ::open(path.c_str(), O_RDONLY);
    xlate5::TranslatorOptions options;
    options.input_name = path;
    xlate5::Translator translator(k, options);
    xlate5::LineReader reader(fd, path);
    const int null_fd = ::open("/dev/null", O_WRONLY);
    xlate5::OutputSink sink(null_fd);
    auto cpu_now = [] {
        timespec ts{};
        ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
        return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
    };
    const double c0 = cpu_now();
    const auto t0 = std::chrono::steady_clock::now();
    const auto stats = xlate5::translate_stream(reader, translator, sink);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double cpu = cpu_now() - c0;
    ::close(fd);
    ::close(null_fd);
    if (!keep) ::unlink(path.c_str());

    rusage ru{};
    ::getrusage(RUSAGE_SELF, &ru);
    std::printf("machine %s, %s, %llu lines in, %llu lines out (%.2f per line in), %.1f MB in, %.1f MB out\n", machine.c_str(),
                m.motion.segment ? ("tolerance " + std::to_string(m.motion.tolerance) + " mm").c_str() : "no splitting",
                (unsigned long long)stats.lines_in, (unsigned long long)stats.lines_out, double(stats.lines_out) / double(stats.lines_in),
                double(stats.bytes_in) / 1e6, double(stats.bytes_out) / 1e6);
    std::printf("time %.3f s: %.2f M lines/s, %.1f MB/s (input), peak RSS %.1f MB\n", seconds,
                double(stats.lines_in) / seconds / 1e6, double(stats.bytes_in) / seconds / 1e6, double(ru.ru_maxrss) / 1024.0);
    std::printf("cpu %.3f s: %.2f M lines/s per CPU second\n", cpu, double(stats.lines_in) / cpu / 1e6);
    return 0;
}
