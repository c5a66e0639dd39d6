// SPDX-License-Identifier: GPL-3.0-or-later
// Where the service's log goes, and how often one kind of message may be written (stage: the
// service's logging; calls the C library only).
#pragma once
#include <chrono>
#include <cstdint>

namespace xlate5 {

// systemd's rule (systemd.exec(5), "$JOURNAL_STREAM"): standard error is connected to the
// journal when JOURNAL_STREAM is "DEVICE:INODE" and those are the device and inode of `fd`.
// Set but not matching (inherited by a program started from a service, then redirected), the
// log stays on standard error.
bool journal_stream_is(int fd, const char* journal_stream);

// At most `burst` messages in any `window`; the ones past it are counted, and the next message
// allowed says how many were left out. A sender can refuse itself a line a millisecond; the log
// keeps the first ones whole and a count of the rest.
class LogBudget {
public:
    using Clock = std::chrono::steady_clock;
    LogBudget(unsigned burst, Clock::duration window) : burst_(burst), window_(window) {}
    // True when this message may be written; `suppressed` is then the count left out before it.
    bool allow(Clock::time_point now, std::uint64_t& suppressed);

private:
    unsigned burst_;
    Clock::duration window_;
    Clock::time_point start_{};
    unsigned used_ = 0;
    std::uint64_t dropped_ = 0;
    bool started_ = false;
};

}  // namespace xlate5
