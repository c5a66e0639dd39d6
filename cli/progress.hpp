// SPDX-License-Identifier: GPL-3.0-or-later
// Progress of a long offline translation on standard error (stage: command line; calls nothing
// of the pipeline). Drawn only when standard error is a terminal, from the stream loop's
// once-per-block-read callback, at most four times a second and only after the first second, so
// short runs, pipes and logs see nothing.
#pragma once
#include <chrono>
#include <cstdint>

namespace xlate5::cli {

class Progress {
public:
    // total_bytes: the input's size when known (a regular file), else 0. fd: where to draw.
    Progress(std::uint64_t total_bytes, bool enabled, int fd = 2);
    ~Progress();  // clears the bar, so an error or the shell prompt starts on a clean line
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;

    void update(std::uint64_t bytes_in, std::uint64_t lines_in);
    bool drawn() const { return drawn_; }

private:
    using Clock = std::chrono::steady_clock;
    std::uint64_t total_;
    bool enabled_;
    int fd_;
    bool drawn_ = false;
    Clock::time_point start_, last_;
};

}  // namespace xlate5::cli
