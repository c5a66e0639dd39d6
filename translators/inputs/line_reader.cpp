// SPDX-License-Identifier: GPL-3.0-or-later
// The first stage: lines in. What it may call: see line_reader.hpp.
#include "translators/inputs/line_reader.hpp"

#include <cerrno>
#include <cstring>
#include <unistd.h>

#include "translators/error.hpp"

namespace xlate5 {

namespace {
constexpr std::size_t kChunk = 1u << 20;
}  // namespace

LineReader::LineReader(int fd, std::string name, std::size_t max_line)
    : fd_(fd), name_(std::move(name)), max_line_(max_line) {
    buf_.resize(kChunk);
}

bool LineReader::fill() {
    // Keep the unfinished line, move it to the front, and read more after it.
    if (begin_ > 0) {
        std::memmove(buf_.data(), buf_.data() + begin_, end_ - begin_);
        end_ -= begin_;
        begin_ = 0;
    }
    if (buf_.size() - end_ < kChunk / 2) buf_.resize(buf_.size() + kChunk);
    for (;;) {
        const ssize_t n = ::read(fd_, buf_.data() + end_, buf_.size() - end_);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) throw IoError(name_ + ": read error: " + std::strerror(errno));
        if (n == 0) {
            eof_ = true;
            return false;
        }
        end_ += std::size_t(n);
        total_ += std::uint64_t(n);
        return true;
    }
}

bool LineReader::has_line() const {
    return eof_ || std::memchr(buf_.data() + begin_, '\n', end_ - begin_) != nullptr;
}

bool LineReader::next_after_read(std::string_view& line) {
    // next() has scanned the pending bytes: no '\n' among them.
    for (;;) {
        if (end_ - begin_ > max_line_)
            throw InputError(name_, line_no_ + 1, 1, "line longer than " + std::to_string(max_line_) + " bytes");
        const std::size_t pending = end_ - begin_;
        if (eof_ || !fill()) {
            if (end_ == begin_) return false;
            line = std::string_view(buf_.data() + begin_, end_ - begin_);  // last line without '\n'
            begin_ = end_;
            ++line_no_;
            return true;
        }
        // fill() moved the pending line to the front; its bytes are scanned.
        const void* nl = std::memchr(buf_.data() + pending, '\n', end_ - pending);
        if (nl) {
            const std::size_t pos = std::size_t(static_cast<const char*>(nl) - buf_.data());
            line = std::string_view(buf_.data() + begin_, pos - begin_);
            begin_ = pos + 1;
            ++line_no_;
            return true;
        }
    }
}

}  // namespace xlate5
