#include "translators/stream.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "translators/error.hpp"
#include "translators/translator.hpp"

namespace xlate5 {

namespace {
constexpr std::size_t kChunk = 1u << 20;
constexpr std::size_t kFlushAt = 1u << 18;
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

bool LineReader::next(std::string_view& line) {
    std::size_t scanned = begin_;
    for (;;) {
        const void* nl = std::memchr(buf_.data() + scanned, '\n', end_ - scanned);
        if (nl) {
            const std::size_t pos = std::size_t(static_cast<const char*>(nl) - buf_.data());
            line = std::string_view(buf_.data() + begin_, pos - begin_);
            begin_ = pos + 1;
            ++line_no_;
            return true;
        }
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
        scanned = pending;  // fill() moved the pending line to the front; its bytes are scanned
    }
}

OutputSink::OutputSink(const std::string& path) : path_(path) {
    if (path.empty() || path == "-") return;
    temp_ = path + ".xlate5-XXXXXX";
    fd_ = ::mkstemp(temp_.data());
    if (fd_ < 0) throw IoError(path + ": cannot create output file: " + std::strerror(errno));
    ::fchmod(fd_, 0644);
}

OutputSink::~OutputSink() {
    if (!temp_.empty() && !committed_) {
        ::close(fd_);
        ::unlink(temp_.c_str());
    }
}

void OutputSink::write(std::string_view text) {
    while (!text.empty()) {
        const ssize_t n = ::write(fd_, text.data(), text.size());
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) throw IoError((temp_.empty() ? std::string("standard output") : path_) + ": write error: " + std::strerror(errno));
        text.remove_prefix(std::size_t(n));
    }
}

void OutputSink::commit() {
    if (temp_.empty()) return;
    if (::fsync(fd_) != 0 || ::close(fd_) != 0) throw IoError(path_ + ": cannot write output file: " + std::strerror(errno));
    committed_ = true;
    if (::rename(temp_.c_str(), path_.c_str()) != 0) {
        const int err = errno;
        ::unlink(temp_.c_str());
        throw IoError(path_ + ": cannot rename the finished output into place: " + std::strerror(err));
    }
}

StreamStats translate_stream(LineReader& reader, Translator& translator, OutputSink& sink) {
    StreamStats stats;
    std::string out;
    out.reserve(kFlushAt + 4096);
    std::string_view line;
    translator.set_lookback(Translator::kDefaultLookback);  // a limit further on can be unwound on an earlier travel move
    while (reader.next(line)) {
        translator.feed(line, reader.line_number(), out);
        if (out.size() >= kFlushAt) {
            sink.write(out);
            stats.bytes_out += out.size();
            stats.lines_out += std::uint64_t(std::count(out.begin(), out.end(), '\n'));
            out.clear();
        }
    }
    translator.finish(out);
    sink.write(out);
    stats.bytes_out += out.size();
    stats.lines_out += std::uint64_t(std::count(out.begin(), out.end(), '\n'));
    stats.lines_in = reader.line_number();
    stats.bytes_in = reader.bytes_read();
    return stats;
}

}  // namespace xlate5
