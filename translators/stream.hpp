// Stage 1 and the sink: lines in from a file descriptor, text out to one, in large chunks so
// memory stays flat whatever the file size; an output file is replaced atomically on success.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>

namespace xlate5 {

class Translator;

// Reads '\n'-terminated lines (the last may lack it) from `fd`, which it does not own.
class LineReader {
public:
    explicit LineReader(int fd, std::string name, std::size_t max_line = 64u << 20);
    // The next line without its '\n'; false at end of input. Throws InputError for a line longer
    // than max_line, IoError for a read error.
    bool next(std::string_view& line);
    std::uint64_t line_number() const { return line_no_; }
    std::uint64_t bytes_read() const { return total_; }

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

// Where translated text goes: standard output, or a file that appears only when complete.
class OutputSink {
public:
    // path "-" or empty: standard output. Otherwise a temporary file next to `path`.
    explicit OutputSink(const std::string& path);
    // An already open descriptor (not owned), e.g. a pipe or /dev/null.
    explicit OutputSink(int fd) : fd_(fd) {}
    ~OutputSink();  // without commit(), the temporary file is removed
    OutputSink(const OutputSink&) = delete;
    OutputSink& operator=(const OutputSink&) = delete;

    void write(std::string_view text);
    void commit();  // flush, fsync, and rename over `path`

private:
    int fd_ = 1;
    std::string path_, temp_;
    bool committed_ = false;
};

struct StreamStats {
    std::uint64_t lines_in = 0;
    std::uint64_t bytes_in = 0;
    std::uint64_t bytes_out = 0;
    std::uint64_t lines_out = 0;
};

// Runs every line of `reader` through `translator` into `sink`.
StreamStats translate_stream(LineReader& reader, Translator& translator, OutputSink& sink);

}  // namespace xlate5
