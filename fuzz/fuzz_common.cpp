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
        std::vector<std::string> paths;
        for (const auto& e : std::filesystem::directory_iterator(XLATE5_SOURCE_MACHINES))
            if (e.path().extension() == ".toml") paths.push_back(e.path().string());
        std::sort(paths.begin(), paths.end());
        std::vector<Machine> out;
        for (const auto& p : paths) out.push_back(load_machine(p));
        if (out.empty()) std::abort();  // nothing to fuzz against: the source tree is not where it was built from
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
