// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/log_policy.hpp"

#include <cerrno>
#include <cstdlib>
#include <sys/stat.h>

namespace xlate5 {

bool journal_stream_is(int fd, const char* journal_stream) {
    if (!journal_stream || !*journal_stream) return false;
    // "DEVICE:INODE", both decimal (systemd writes them with %lu).
    errno = 0;
    char* end = nullptr;
    const unsigned long long dev = std::strtoull(journal_stream, &end, 10);
    if (errno || end == journal_stream || *end != ':') return false;
    const char* ino_text = end + 1;
    const unsigned long long ino = std::strtoull(ino_text, &end, 10);
    if (errno || end == ino_text || *end) return false;
    struct stat st {};
    if (::fstat(fd, &st) != 0) return false;
    return static_cast<unsigned long long>(st.st_dev) == dev && static_cast<unsigned long long>(st.st_ino) == ino;
}

bool LogBudget::allow(Clock::time_point now, std::uint64_t& suppressed) {
    if (!started_ || now - start_ >= window_) {
        started_ = true;
        start_ = now;
        used_ = 0;
    }
    if (used_ >= burst_) {
        ++dropped_;
        return false;
    }
    ++used_;
    suppressed = dropped_;
    dropped_ = 0;
    return true;
}

}  // namespace xlate5
