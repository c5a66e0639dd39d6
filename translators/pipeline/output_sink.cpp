// SPDX-License-Identifier: GPL-3.0-or-later
// The sink: text out, atomically to a file. What it may call: see output_sink.hpp.
#include "translators/pipeline/output_sink.hpp"

#include <atomic>
#include <cerrno>
#include <climits>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <mutex>
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include "translators/error.hpp"

namespace xlate5 {

namespace {

// Temporary output files to remove if a signal ends the process. Lock-free atomics, since the
// handler may run between any two instructions of the code that registers them.
std::atomic<const char*> g_pending[OutputSink::kMaxPending];
static_assert(std::atomic<const char*>::is_always_lock_free);
constexpr int kCleanupSignals[] = {SIGINT, SIGTERM, SIGHUP};

// Async-signal-safe: unlink, sigaction and raise only. The signal is blocked while the handler
// runs, so the raise() takes effect, with the default action, as it returns: the process ends as
// the signal says (a shell sees 130 for SIGINT).
extern "C" void remove_pending_and_reraise(int sig) {
    for (auto& pending : g_pending)
        if (const char* path = pending.exchange(nullptr)) ::unlink(path);
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    sigemptyset(&dfl.sa_mask);
    ::sigaction(sig, &dfl, nullptr);
    ::raise(sig);
}

// Once per process, and only for signals nobody else handles or ignores (the service has its own).
void install_cleanup_handlers() {
    static std::once_flag once;
    std::call_once(once, [] {
        for (int sig : kCleanupSignals) {
            struct sigaction old {};
            if (::sigaction(sig, nullptr, &old) != 0) continue;
            if ((old.sa_flags & SA_SIGINFO) || old.sa_handler != SIG_DFL) continue;
            struct sigaction sa {};
            sa.sa_handler = remove_pending_and_reraise;
            sigfillset(&sa.sa_mask);
            ::sigaction(sig, &sa, nullptr);
        }
    });
}

// Blocks the cleanup signals for its lifetime: a temporary file is created and registered as one step.
class SignalsBlocked {
public:
    SignalsBlocked() {
        sigset_t set;
        sigemptyset(&set);
        for (int sig : kCleanupSignals) sigaddset(&set, sig);
        ::pthread_sigmask(SIG_BLOCK, &set, &old_);
    }
    ~SignalsBlocked() { ::pthread_sigmask(SIG_SETMASK, &old_, nullptr); }

private:
    sigset_t old_;
};

int register_pending(const char* path) {
    for (int i = 0; i < OutputSink::kMaxPending; ++i) {
        const char* expected = nullptr;
        if (g_pending[i].compare_exchange_strong(expected, path)) return i;
    }
    return -1;
}

void unregister_pending(int slot) {
    if (slot >= 0) g_pending[slot].store(nullptr);
}

// The file a path finally names: its symlinks followed (a dangling one to the file it would
// create), so the link itself is kept. Directories on the way are the kernel's business.
std::string follow_links(const std::string& path) {
    std::string p = path;
    for (int hops = 0; hops < 40; ++hops) {
        struct stat st {};
        if (::lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return p;
        std::string target(std::size_t(PATH_MAX), '\0');
        const ssize_t n = ::readlink(p.c_str(), target.data(), target.size());
        if (n < 0) throw IoError(path + ": cannot read the symbolic link: " + std::strerror(errno));
        target.resize(std::size_t(n));
        if (target.empty()) return p;
        if (target.front() != '/') {
            const auto slash = p.rfind('/');
            target = (slash == std::string::npos ? std::string() : p.substr(0, slash + 1)) + target;
        }
        p = target;
    }
    throw IoError(path + ": too many levels of symbolic links");
}

// May the user replace this existing file? Only if they could write it: by its permissions for
// a user, and for root (whom permissions do not stop) if any write bit is set at all.
bool may_replace(const std::string& path, const struct stat& st) {
    if (::geteuid() == 0) return (st.st_mode & 0222) != 0;
    return ::faccessat(AT_FDCWD, path.c_str(), W_OK, AT_EACCESS) == 0;
}

std::string octal_mode(mode_t mode) {
    char buf[8];
    std::snprintf(buf, sizeof buf, "%04o", unsigned(mode & 07777));
    return buf;
}

}  // namespace

OutputSink::OutputSink(const std::string& path) : path_(path) {
    if (path.empty() || path == "-") return;
    // Standard output by name: the descriptor itself (its link names a pipe or terminal, or a file
    // the shell opened, perhaps for appending).
    if (path == "/dev/stdout" || path == "/dev/fd/1" || path == "/proc/self/fd/1") return;
    struct stat st {};
    const bool exists = ::stat(path.c_str(), &st) == 0;  // through every link, as the kernel follows them
    if (!exists && errno != ENOENT) throw IoError(path + ": cannot write output file: " + std::strerror(errno));
    if (exists && S_ISDIR(st.st_mode)) throw IoError(path + ": is a directory");
    if (exists && !S_ISREG(st.st_mode)) {
        // A device, FIFO or socket: written in place. Replacing it would destroy it (a device
        // node turned into a plain file) and cut off whoever reads it.
        fd_ = ::open(path.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
        if (fd_ < 0) throw IoError(path + ": cannot open for writing: " + std::strerror(errno));
        owned_ = true;
        return;
    }
    target_ = follow_links(path);  // a regular file, or none yet: where the temporary goes
    if (exists && !may_replace(target_, st))
        throw IoError(path + ": the file is read-only (mode " + octal_mode(st.st_mode) +
                      "): not replaced; make it writable, or write the output elsewhere");
    mode_t mode = 0;
    if (exists) {
        mode = st.st_mode & 07777;
    } else {
        const mode_t mask = ::umask(0);
        ::umask(mask);
        mode = 0666 & ~mask;
    }
    install_cleanup_handlers();
    temp_ = target_ + ".xlate5-XXXXXX";
    int err = 0;
    {
        const SignalsBlocked blocked;
        fd_ = ::mkostemp(temp_.data(), O_CLOEXEC);
        err = errno;
        if (fd_ >= 0) slot_ = register_pending(temp_.c_str());
    }
    if (fd_ < 0) {
        temp_.clear();
        fd_ = 1;
        throw IoError(path + ": cannot create output file: " + std::strerror(err));
    }
    owned_ = true;
    if (slot_ < 0) {
        ::close(fd_);
        owned_ = false;
        ::unlink(temp_.c_str());
        temp_.clear();
        throw IoError(path + ": more than " + std::to_string(kMaxPending) + " output files at once");
    }
    // Owner first: a change of owner clears set-user/group-ID bits, which the mode then restores.
    if (exists && ::geteuid() == 0 && ::fchown(fd_, st.st_uid, st.st_gid) != 0)
        throw IoError(path + ": cannot keep the file's owner: " + std::strerror(errno));
    if (::fchmod(fd_, mode) != 0) throw IoError(path + ": cannot keep the file's mode: " + std::strerror(errno));
}

OutputSink::~OutputSink() {
    if (owned_) ::close(fd_);
    // Removed before it is unregistered: a signal in between finds it gone, never left behind.
    if (!temp_.empty() && !committed_) ::unlink(temp_.c_str());
    unregister_pending(slot_);
}

void OutputSink::write(std::string_view text) {
    while (!text.empty()) {
        const ssize_t n = ::write(fd_, text.data(), text.size());
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) throw IoError((owned_ ? path_ : std::string("standard output")) + ": write error: " + std::strerror(errno));
        text.remove_prefix(std::size_t(n));
    }
}

void OutputSink::commit() {
    if (!owned_ || committed_) return;
    const bool in_place = temp_.empty();
    // A device or FIFO cannot be fsync'd (EINVAL): closing it is all there is.
    const bool synced = in_place || ::fsync(fd_) == 0;
    int err = errno;
    const bool closed = ::close(fd_) == 0;
    if (!closed) err = errno;
    owned_ = false;
    if (!synced || !closed) throw IoError(path_ + ": cannot write output file: " + std::strerror(err));
    if (in_place) {
        committed_ = true;
        return;
    }
    if (::rename(temp_.c_str(), target_.c_str()) != 0) {
        err = errno;
        throw IoError(path_ + ": cannot rename the finished output into place: " + std::strerror(err));  // the destructor removes it
    }
    committed_ = true;
    unregister_pending(slot_);
    slot_ = -1;
}

}  // namespace xlate5
