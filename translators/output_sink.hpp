// The sink, last after the emitter: text out to a file descriptor; an output file is replaced
// atomically, and only when the whole translation succeeded. May call: nothing of the pipeline.
#pragma once
#include <string>
#include <string_view>

namespace xlate5 {

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

}  // namespace xlate5
