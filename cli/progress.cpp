// SPDX-License-Identifier: GPL-3.0-or-later
// The progress bar. What it may call: see progress.hpp.
#include "cli/progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <string>

namespace xlate5::cli {

namespace {
constexpr auto kFirstAfter = std::chrono::seconds(1);
constexpr auto kEvery = std::chrono::milliseconds(250);
constexpr int kWidth = 30;

void put(int fd, const std::string& s) {
    for (std::size_t done = 0; done < s.size();) {
        const ssize_t n = ::write(fd, s.data() + done, s.size() - done);
        if (n <= 0) return;  // a bar is not worth an error
        done += std::size_t(n);
    }
}
}  // namespace

Progress::Progress(std::uint64_t total_bytes, bool enabled, int fd)
    : total_(total_bytes), enabled_(enabled), fd_(fd), start_(Clock::now()), last_(start_) {}

Progress::~Progress() {
    if (drawn_) put(fd_, "\r\033[K");
}

void Progress::update(std::uint64_t bytes_in, std::uint64_t lines_in) {
    if (!enabled_) return;
    const auto now = Clock::now();
    if (now - start_ < kFirstAfter || (drawn_ && now - last_ < kEvery)) return;
    last_ = now;
    const double seconds = std::chrono::duration<double>(now - start_).count();
    const double mb = double(bytes_in) / 1e6, rate = mb / seconds;
    char text[200];
    if (total_ > 0) {
        const double share = std::min(1.0, double(bytes_in) / double(total_));
        std::string bar(std::size_t(share * kWidth), '#');
        bar.resize(kWidth, '.');
        const double left = rate > 0 ? (double(total_) / 1e6 - mb) / rate : 0;
        std::snprintf(text, sizeof text, "\rxlate5: [%s] %3.0f%%  %.1f of %.1f MB, %llu lines, %.1f MB/s, %.0f s left\033[K", bar.c_str(),
                      share * 100, mb, double(total_) / 1e6, static_cast<unsigned long long>(lines_in), rate, std::max(0.0, left));
    } else {
        std::snprintf(text, sizeof text, "\rxlate5: %.1f MB, %llu lines, %.1f MB/s\033[K", mb, static_cast<unsigned long long>(lines_in), rate);
    }
    put(fd_, text);
    drawn_ = true;
}

}  // namespace xlate5::cli
