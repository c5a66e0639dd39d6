// The sink: text out, atomically to a file. What it may call: see output_sink.hpp.
#include "translators/output_sink.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "translators/error.hpp"

namespace xlate5 {

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

}  // namespace xlate5
