// SPDX-License-Identifier: GPL-3.0-or-later
// Shared by the fuzz targets (stage: test harness; may call the machine file reader).
#include "fuzz/fuzz_common.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

namespace xlate5::fuzz {

const std::vector<Machine>& bundled() {
    static const std::vector<Machine> machines = [] {
        // Read from the source tree the target was built in: without it there is nothing to fuzz
        // against, and that is the harness's setup, not a finding, so say so plainly and stop.
        const auto missing = [] {
            std::fprintf(stderr, "fuzz: no machine files in %s (the source tree this target was built from)\n", XLATE5_SOURCE_MACHINES);
            std::abort();
        };
        std::error_code ec;
        std::filesystem::directory_iterator dir(XLATE5_SOURCE_MACHINES, ec);
        if (ec) missing();
        std::vector<std::string> paths;
        for (const auto& e : dir)
            if (e.path().extension() == ".toml") paths.push_back(e.path().string());
        std::sort(paths.begin(), paths.end());
        std::vector<Machine> out;
        for (const auto& p : paths) out.push_back(load_machine(p));
        if (out.empty()) missing();
        return out;
    }();
    return machines;
}

const std::string& as_file(const std::uint8_t* data, std::size_t size) {
    static const int fd = ::memfd_create("xlate5-fuzz", 0);
    static const std::string path = "/proc/self/fd/" + std::to_string(fd);
    if (fd < 0 || ::ftruncate(fd, 0) != 0 || ::lseek(fd, 0, SEEK_SET) != 0) std::abort();
    for (std::size_t done = 0; done < size;) {
        const ssize_t n = ::write(fd, data + done, size - done);
        if (n <= 0) std::abort();
        done += std::size_t(n);
    }
    return path;
}

}  // namespace xlate5::fuzz
