// SPDX-License-Identifier: GPL-3.0-or-later
// Fuzz target: the measurement tables of `xlate5 calibrate` (CSV readers and the fits behind
// them), driven through the command line's own parsing: fit (orders 1..12), plate, offset,
// centre, and pivots against a bundled machine fitting some of its parameters.
// Stage: test harness; may call the calibrate commands (cli/calibrate_cmd.cpp).
// Input: byte 0 picks the command (and the order or the machine), byte 1 the parameters pivots
// fits (one bit each), the rest is the file. Printed results go to /dev/null.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cli/calibrate_cmd.hpp"
#include "fuzz/fuzz_common.hpp"

using namespace xlate5;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    // The commands print with printf and iostreams; thousands of runs a second would flood the log.
    if (!std::freopen("/dev/null", "w", stdout)) std::abort();
    std::cerr.setstate(std::ios::badbit);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 2) return 0;
    const auto& machines = fuzz::bundled();
    const unsigned pick = data[0], params = data[1];
    const std::string& path = fuzz::as_file(data + 2, size - 2);

    std::vector<std::string> args = {"xlate5", "calibrate"};
    cli::Common common;
    switch (pick % 5u) {
    case 0: args.insert(args.end(), {"fit", path, "--order", std::to_string(1 + (pick / 5u) % 12u)}); break;
    case 1: args.insert(args.end(), {"plate", path}); break;
    case 2: args.insert(args.end(), {"offset", path}); break;
    case 3: args.insert(args.end(), {"centre", path}); break;
    default: {
        const Machine& m = machines[(pick / 5u) % machines.size()];
        common.machine = m.source_path;
        std::string fit;
        unsigned bit = 0;
        for (const auto& p : m.parameters)
            if (bit < 8 && (params >> bit++) & 1u) fit += (fit.empty() ? "" : ",") + p.first;
        if (fit.empty()) return 0;
        args.insert(args.end(), {"pivots", path, "--fit", fit});
    }
    }
    // The command line and machine depend only on bytes 0-1 (the file's path is fixed), so each
    // distinct pair is parsed once and kept: building CLI11's parser per input was a tenth of the time.
    struct Parsed {
        CLI::App app{"xlate5", "xlate5"};
        std::unique_ptr<cli::CalibrateCommands> commands;
        cli::Common common;
    };
    static std::map<std::vector<std::string>, std::unique_ptr<Parsed>> parsed;  // at most a few hundred
    std::vector<std::string> key = args;
    key.push_back(common.machine);
    auto& slot = parsed[key];
    if (!slot) {
        slot = std::make_unique<Parsed>();
        slot->commands = cli::add_calibrate_commands(slot->app);
        slot->common = common;
        std::vector<char*> argv;
        for (auto& a : args) argv.push_back(a.data());
        slot->app.parse(int(argv.size()), argv.data());  // our own arguments: a parse error here is the harness's bug
    }
    (void)cli::run_calibrate_commands(*slot->commands, slot->common);
    return 0;
}
