// The first stage: lines in from a file descriptor, in large chunks so memory stays flat
// whatever the file size. May call: nothing of the pipeline.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>

namespace xlate5 {

// Reads '\n'-terminated lines (the last may lack it) from `fd`, which it does not own.
class LineReader {
public:
    explicit LineReader(int fd, std::string name, std::size_t max_line = 64u << 20);
    // The next line without its '\n'; false at end of input. Throws InputError for a line longer
    // than max_line, IoError for a read error.
    bool next(std::string_view& line);
    std::uint64_t line_number() const { return line_no_; }
    std::uint64_t bytes_read() const { return total_; }
    // True when next() can return a line without reading: when false, the next call may wait on
    // a pipe or a terminal, so a filter writes out what it has first.
    bool has_line() const;

private:
    bool fill();

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
