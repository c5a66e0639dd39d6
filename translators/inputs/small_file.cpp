// SPDX-License-Identifier: GPL-3.0-or-later
// Whole small files, bounded. What it may call: see small_file.hpp.
#include "translators/inputs/small_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>

#include "translators/error.hpp"

namespace xlate5 {

std::string read_small_file(const std::string& path, std::size_t max_bytes, const std::string& what) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw IoError(path + ": cannot open: " + std::strerror(errno));
    std::string text;
    // One byte past the bound tells a file of exactly max_bytes from a longer one.
    const std::size_t want = max_bytes + 1;
    text.resize(std::min<std::size_t>(want, 64u << 10));
    std::size_t have = 0;
    for (;;) {
        if (have == text.size()) {
            if (text.size() == want) break;
            text.resize(std::min(want, 2 * text.size()));
        }
        const ssize_t n = ::read(fd, text.data() + have, text.size() - have);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
            const int err = errno;
            ::close(fd);
            throw IoError(path + ": read error: " + std::strerror(err));
        }
        if (n == 0) break;
        have += std::size_t(n);
    }
    ::close(fd);
    if (have > max_bytes) {
        // The place of the first byte past the bound.
        std::uint64_t line = 1;
        std::size_t line_start = 0;
        for (std::size_t i = 0; i < max_bytes; ++i)
            if (text[i] == '\n') ++line, line_start = i + 1;
        throw InputError(path, line, std::uint32_t(max_bytes - line_start + 1),
                         "longer than " + std::to_string(max_bytes) + " bytes, the bound for " + what + " (docs/limits.md)");
    }
    text.resize(have);
    return text;
}

}  // namespace xlate5
