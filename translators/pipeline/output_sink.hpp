// SPDX-License-Identifier: GPL-3.0-or-later
// The sink, last after the emitter: text out to a file descriptor; an output file is replaced
// atomically, and only when the whole translation succeeded. May call: nothing of the pipeline.
#pragma once
#include <string>
#include <string_view>

namespace xlate5 {

// Where translated text goes: standard output, or a file that appears only when complete.
// `-o PATH` never harms what PATH names:
// - a regular file (or a symlink to one, which stays a link: its target is replaced) is written
//   to a temporary file next to it and renamed over it on commit(), keeping its mode (and, as
//   root, its owner and group); without commit() the temporary is removed, also when the process
//   is stopped by SIGINT, SIGTERM or SIGHUP. The input may be the same file: it is read from the
//   original, which is replaced only at the end.
// - an existing file that the user may not write is not replaced (IoError); as root, a file
//   with no write permission bit at all counts as not writable.
// - anything else that exists (/dev/null, a FIFO, a terminal) is opened and written in place,
//   never replaced; like standard output, what was written before an error stays written.
//   /dev/stdout (and /dev/fd/1, /proc/self/fd/1) is standard output itself.
class OutputSink {
public:
    // path "-" or empty: standard output.
    explicit OutputSink(const std::string& path);
    // An already open descriptor (not owned), e.g. a pipe or /dev/null.
    explicit OutputSink(int fd) : fd_(fd) {}
    ~OutputSink();  // without commit(), the temporary file is removed
    OutputSink(const OutputSink&) = delete;
    OutputSink& operator=(const OutputSink&) = delete;

    void write(std::string_view text);
    void commit();  // flush, fsync, and rename over the target (in place: close)
    // The temporary file written so far, before commit() (to read it back); "" for standard
    // output and a file written in place.
    const std::string& temporary() const { return temp_; }

    // Temporary files at most registered at once for removal on a signal (a process writes its
    // output, a report and a plot); a further sink throws IoError.
    static constexpr int kMaxPending = 8;

private:
    int fd_ = 1;
    bool owned_ = false;       // fd_ is ours to close
    std::string path_;         // as given, for messages
    std::string target_;       // the file replaced on commit (a symlink's target)
    std::string temp_;         // the temporary next to it ("" when writing in place or to stdout)
    int slot_ = -1;            // its registration for removal on a signal
    bool committed_ = false;
};

}  // namespace xlate5
