// SPDX-License-Identifier: GPL-3.0-or-later
// The slicer's time lines rewritten. What it may call: see slicer_times.hpp.
#include "translators/inspect/slicer_times.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include <cerrno>
#include <fcntl.h>
#include <unistd.h>

#include "translators/error.hpp"

namespace xlate5 {

namespace {

constexpr std::string_view kEstimate = "; estimated printing time (";

bool starts(std::string_view s, std::string_view p) { return s.substr(0, p.size()) == p; }

// Every block of the file at `path`, in order.
template <class F>
void read_blocks(const std::string& path, std::string& buffer, F&& f) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw IoError(path + ": cannot read the output back: " + std::strerror(errno));
    for (;;) {
        const ssize_t n = ::read(fd, buffer.data(), buffer.size());
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
            const int err = errno;
            ::close(fd);
            throw IoError(path + ": cannot read the output back: " + std::strerror(err));
        }
        if (n == 0) break;
        f(std::string_view(buffer.data(), std::size_t(n)));
    }
    ::close(fd);
}

}  // namespace

SlicerTimeLine slicer_time_line(std::string_view l) {
    if (l.size() >= 3 && l[0] == 'M' && l[1] == '7' && l[2] == '3' && (l.size() == 3 || l[3] == ' ' || l[3] == ';' || l[3] == '\r'))
        return SlicerTimeLine::M73;
    if (starts(l, ";TIME:")) return SlicerTimeLine::Total;
    if (starts(l, ";TIME_ELAPSED:")) return SlicerTimeLine::Elapsed;
    if (starts(l, kEstimate) && l.find(" = ", kEstimate.size()) != std::string_view::npos) return SlicerTimeLine::Estimate;
    return SlicerTimeLine::None;
}

bool may_hold_slicer_times(std::string_view b) {
    // Every such line holds "M73" or starts with ';'. Joint-space output has few M and ';' bytes,
    // and memchr passes the rest at a fraction of an instruction a byte (three memmem calls cost
    // 600 instructions an output line, 8 % of a translation).
    const char* const end = b.data() + b.size();
    for (const char* p = b.data(); (p = static_cast<const char*>(std::memchr(p, 'M', std::size_t(end - p)))); ++p)
        if (end - p >= 3 && p[1] == '7' && p[2] == '3') return true;
    for (const char* p = b.data(); (p = static_cast<const char*>(std::memchr(p, ';', std::size_t(end - p)))); ++p) {
        const std::string_view rest(p, std::size_t(end - p));
        if (starts(rest, ";TIME") || starts(rest, kEstimate)) return true;
    }
    return false;
}

std::string time_dhms(double seconds) {
    long s = std::lround(std::floor(std::max(0.0, seconds)));
    const long d = s / 86400, h = s % 86400 / 3600, m = s % 3600 / 60;
    s %= 60;
    char b[64];
    if (d > 0) std::snprintf(b, sizeof b, "%ldd %ldh %ldm %lds", d, h, m, s);
    else if (h > 0) std::snprintf(b, sizeof b, "%ldh %ldm %lds", h, m, s);
    else if (m > 0) std::snprintf(b, sizeof b, "%ldm %lds", m, s);
    else std::snprintf(b, sizeof b, "%lds", s);
    return b;
}

std::string retimed_line(std::string_view l, double elapsed, double total) {
    const SlicerTimeLine kind = slicer_time_line(l);
    if (kind == SlicerTimeLine::None || !(total > 0) || !std::isfinite(total)) return std::string(l);
    elapsed = std::clamp(elapsed, 0.0, total);
    const std::string_view cr = !l.empty() && l.back() == '\r' ? "\r" : "";
    char b[64];
    switch (kind) {
    case SlicerTimeLine::Total:
        std::snprintf(b, sizeof b, ";TIME:%lld", static_cast<long long>(std::llround(total)));
        return b + std::string(cr);
    case SlicerTimeLine::Elapsed:
        std::snprintf(b, sizeof b, ";TIME_ELAPSED:%.6f", elapsed);
        return b + std::string(cr);
    case SlicerTimeLine::Estimate: {
        const std::size_t eq = l.find(" = ", kEstimate.size()) + 3;
        return std::string(l.substr(0, eq)) + time_dhms(total) + std::string(cr);
    }
    default:
        break;
    }
    // M73: each P Q R S word's number replaced, every other byte kept.
    // At the end exactly 100: (100 t) / t may round to just under 100 (t = 96.252640687 does).
    const int percent = elapsed >= total ? 100 : std::min(99, int(100 * elapsed / total));
    const long minutes = long((total - elapsed + 0.5) / 60);
    std::string out;
    const std::size_t code_end = std::min(l.find(';'), l.size());
    std::size_t i = 3;
    out.append(l.substr(0, 3));
    while (i < code_end) {
        const char c = l[i];
        const bool after_blank = l[i - 1] == ' ' || l[i - 1] == '\t';
        if (after_blank && (c == 'P' || c == 'Q' || c == 'R' || c == 'S')) {
            std::size_t j = i + 1;
            while (j < code_end && (std::isdigit(static_cast<unsigned char>(l[j])) || l[j] == '.' || l[j] == '-' || l[j] == '+')) ++j;
            if (j > i + 1) {
                out += c;
                out += std::to_string(c == 'P' || c == 'Q' ? long(percent) : minutes);
                i = j;
                continue;
            }
        }
        out += c;
        ++i;
    }
    out.append(l.substr(code_end));
    return out;
}

SlicerTimes::SlicerTimes(const Machine& machine, double baud) : preflight_(machine, baud) {
    // Each time line's elapsed time: the blocks and dwells before it, summed as they run.
    preflight_.executed = [this](std::uint64_t line, double seconds) {
        while (resolved_ < at_.size() && at_[resolved_].line < line) at_[resolved_++].elapsed = elapsed_;
        elapsed_ += seconds;
    };
}

void SlicerTimes::line(std::string_view l, std::uint64_t offset) {
    ++lines_;
    // Recorded before the pre-flight reads the line: it executes only blocks before it.
    if (slicer_time_line(l.substr(0, l.size() - (!l.empty() && l.back() == '\n'))) != SlicerTimeLine::None) at_.push_back({offset, lines_, 0});
    preflight_.scan(l);
}

void SlicerTimes::scan(std::string_view text) {
    while (!text.empty()) {
        const auto nl = text.find('\n');
        if (nl == std::string_view::npos) {
            pending_.append(text);
            offset_ += text.size();
            return;
        }
        const std::uint64_t start = offset_ - pending_.size();
        if (pending_.empty()) {
            line(text.substr(0, nl + 1), start);
        } else {
            pending_.append(text.substr(0, nl + 1));
            line(pending_, start);
            pending_.clear();
        }
        offset_ += nl + 1;
        text.remove_prefix(nl + 1);
    }
}

void SlicerTimes::finish() {
    if (!pending_.empty()) line(pending_ + "\n", offset_ - pending_.size()), pending_.clear();
    preflight_.finish();
    total_ = elapsed_;
    for (; resolved_ < at_.size(); ++resolved_) at_[resolved_].elapsed = total_;
}

void SlicerTimes::rewrite(std::string_view text, std::string& out) {
    while (!text.empty()) {
        if (in_line_) {
            const auto nl = text.find('\n');
            if (nl == std::string_view::npos) {
                pending_.append(text);
                out_offset_ += text.size();
                return;
            }
            pending_.append(text.substr(0, nl));
            out += retimed_line(pending_, at_[next_].elapsed, total_);
            out += '\n';
            pending_.clear();
            in_line_ = false;
            ++next_;
            out_offset_ += nl + 1;
            text.remove_prefix(nl + 1);
            continue;
        }
        const std::uint64_t next = next_ < at_.size() ? at_[next_].offset : std::numeric_limits<std::uint64_t>::max();
        if (next >= out_offset_ + text.size()) {
            out.append(text);
            out_offset_ += text.size();
            return;
        }
        const std::size_t n = std::size_t(next - out_offset_);
        out.append(text.substr(0, n));
        out_offset_ += n;
        text.remove_prefix(n);
        in_line_ = true;
    }
}

void SlicerTimes::rewrite_end(std::string& out) {
    if (in_line_) out += retimed_line(pending_, at_[next_].elapsed, total_), ++next_;
    pending_.clear();
    in_line_ = false;
}

}  // namespace xlate5

namespace xlate5 {

std::uint64_t retime_file(const Machine& machine, double baud, const std::string& path, OutputSink& out) {
    SlicerTimes times(machine, baud);
    std::string buffer(1u << 20, '\0'), text;
    read_blocks(path, buffer, [&](std::string_view block) { times.scan(block); });
    times.finish();
    text.reserve(buffer.size() + 4096);
    read_blocks(path, buffer, [&](std::string_view block) {
        times.rewrite(block, text);
        out.write(text);
        text.clear();
    });
    times.rewrite_end(text);
    out.write(text);
    return times.lines();
}

}  // namespace xlate5
