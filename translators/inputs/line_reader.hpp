// SPDX-License-Identifier: GPL-3.0-or-later
// The first stage: lines in from a file descriptor, in large chunks so memory stays flat
// whatever the file size. May call: nothing of the pipeline.
#pragma once
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace xlate5 {

// Reads '\n'-terminated lines (the last may lack it) from `fd`, which it does not own.
class LineReader {
public:
    explicit LineReader(int fd, std::string name, std::size_t max_line = 64u << 20);
    // The next line without its '\n'; false at end of input. Throws InputError for a line longer
    // than max_line, IoError for a read error.
    // Inline for the usual case, a whole line already in the buffer.
    bool next(std::string_view& line) {
        if (const void* nl = std::memchr(buf_.data() + begin_, '\n', end_ - begin_)) {
            const std::size_t pos = std::size_t(static_cast<const char*>(nl) - buf_.data());
            line = std::string_view(buf_.data() + begin_, pos - begin_);
            begin_ = pos + 1;
            ++line_no_;
            return true;
        }
        return next_after_read(line);
    }
    std::uint64_t line_number() const { return line_no_; }
    const std::string& name() const { return name_; }
    std::uint64_t bytes_read() const { return total_; }
    // The bytes of the lines returned so far, their '\n's included (bytes_read() less what is buffered).
    std::uint64_t bytes_consumed() const { return total_ - (end_ - begin_); }
    // True when next() can return a line without reading: when false, the next call may wait on
    // a pipe or a terminal, so a filter writes out what it has first.
    bool has_line() const;

private:
    bool fill();
    // next() when the buffer holds no '\n' from begin_ on: reads more.
    bool next_after_read(std::string_view& line);

    int fd_;
    std::string name_;
    std::size_t max_line_;
    std::string buf_;
    std::size_t begin_ = 0, end_ = 0;
    bool eof_ = false;
    std::uint64_t line_no_ = 0;
    std::uint64_t total_ = 0;
};

}  // namespace xlate5
