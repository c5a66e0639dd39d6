// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/line_protocol.hpp"

#include <cctype>
#include <charconv>

namespace xlate5::proto {
namespace {

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
    return s;
}

bool starts_with_nocase(std::string_view s, std::string_view prefix) {
    if (s.size() < prefix.size()) return false;
    for (std::size_t i = 0; i < prefix.size(); ++i)
        if (std::tolower(static_cast<unsigned char>(s[i])) != std::tolower(static_cast<unsigned char>(prefix[i]))) return false;
    return true;
}

bool contains(std::string_view s, std::string_view what) { return s.find(what) != std::string_view::npos; }

// An integer after optional blanks; advances `s`.
std::optional<std::int64_t> read_int(std::string_view& s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == ':')) s.remove_prefix(1);
    std::int64_t v = 0;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (r.ec != std::errc()) return std::nullopt;
    s.remove_prefix(std::size_t(r.ptr - s.data()));
    return v;
}

}  // namespace

std::uint8_t checksum(std::string_view text) {
    std::uint8_t cs = 0;
    for (char c : text) cs ^= static_cast<std::uint8_t>(c);
    return cs;
}

std::string numbered(std::int64_t n, std::string_view command) {
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on "N" + std::to_string(n).
    std::string line;
    line.reserve(command.size() + 24);
    line += 'N';
    line += std::to_string(n);
    line += ' ';
    line += command;
    const unsigned cs = checksum(line);
    line += '*';
    line += std::to_string(cs);
    return line;
}

Received parse_received(std::string_view line) {
    Received r;
    line = trim(line);
    // The checksum covers everything before the last '*' outside a ';' comment. A '*' without
    // an N is still a checksum (Marlin refuses it: "No Line Number with checksum").
    std::string_view body = line;
    const auto semicolon = line.find(';');
    const auto star = line.substr(0, semicolon).rfind('*');
    if (star != std::string_view::npos) {
        r.has_checksum = true;
        std::string_view digits = trim(line.substr(star + 1, semicolon == std::string_view::npos ? std::string_view::npos : semicolon - star - 1));
        unsigned cs = 0;
        const auto res = std::from_chars(digits.data(), digits.data() + digits.size(), cs);
        r.checksum_ok = res.ec == std::errc() && res.ptr == digits.data() + digits.size() && cs == checksum(line.substr(0, star));
        body = line.substr(0, star);
    }
    if (!body.empty() && body[0] == 'N') {
        std::string_view rest = body.substr(1);
        std::int64_t n = 0;
        const auto res = std::from_chars(rest.data(), rest.data() + rest.size(), n);
        if (res.ec == std::errc()) {
            r.number = n;
            body = rest.substr(std::size_t(res.ptr - rest.data()));
        } else {
            r.bad_number = true;  // "N;01513 G1 …": a flipped digit, not an unnumbered command "N"
        }
    }
    r.command = trim(body);
    return r;
}

std::string strip_comment(std::string_view command) {
    std::string out;
    out.reserve(command.size());
    int depth = 0;
    for (char c : command) {
        if (c == ';' && depth == 0) break;
        if (c == '(') { ++depth; continue; }
        if (c == ')' && depth > 0) { --depth; continue; }
        if (depth == 0) out += c;
    }
    return std::string(trim(out));
}

void append_commands(std::string_view text, std::vector<std::string>& out) {
    std::size_t begin = 0;
    while (begin < text.size()) {
        auto end = text.find('\n', begin);
        if (end == std::string_view::npos) end = text.size();
        std::string cmd = strip_comment(text.substr(begin, end - begin));
        if (!cmd.empty()) out.push_back(std::move(cmd));
        begin = end + 1;
    }
}

std::optional<std::int64_t> m110_line(std::string_view command) {
    const auto p = command.find_first_of("Nn", 1);
    if (p == std::string_view::npos) return std::nullopt;
    std::string_view rest = command.substr(p + 1);
    return read_int(rest);
}

Code command_code(std::string_view command) {
    command = trim(command);
    Code c;
    if (command.size() < 2) return c;
    const char l = char(std::toupper(static_cast<unsigned char>(command[0])));
    if (l != 'G' && l != 'M' && l != 'T') return c;
    std::string_view rest = command.substr(1);
    int whole = 0;
    const auto r = std::from_chars(rest.data(), rest.data() + rest.size(), whole);
    // The G-code lexer's bound on codes (kMaxCode): past it there is no code, and whole * 10
    // cannot overflow. The translator then refuses the command with its column.
    if (r.ec != std::errc() || whole <= -100000 || whole >= 100000) return c;
    int frac = 0;
    if (r.ptr < rest.data() + rest.size() && *r.ptr == '.' && r.ptr + 1 < rest.data() + rest.size() &&
        std::isdigit(static_cast<unsigned char>(r.ptr[1])))
        frac = r.ptr[1] - '0';
    c.letter = l;
    c.code10 = whole * 10 + frac;
    return c;
}

Reply classify(std::string_view line) {
    Reply r;
    line = trim(line);
    if (starts_with_nocase(line, "ok")) {
        r.kind = ReplyKind::Ok;
        r.payload = line.substr(2);
        // ADVANCED_OK: "ok N10 P15 B3"
        std::string_view s = r.payload;
        while (!s.empty()) {
            while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
            if (s.size() < 2) break;
            const char k = s.front();
            std::string_view after = s.substr(1);
            if ((k == 'N' || k == 'P' || k == 'B') && std::isdigit(static_cast<unsigned char>(after.front()))) {
                const auto v = read_int(after);
                if (!v) break;
                if (k == 'N') r.ok_line = *v;
                if (k == 'P') r.planner_free = int(*v);
                if (k == 'B') r.buffer_free = int(*v);
                s = after;
            } else {
                break;
            }
        }
        return r;
    }
    if (starts_with_nocase(line, "resend") || starts_with_nocase(line, "rs ")) {
        std::string_view s = line.substr(line[1] == 's' || line[1] == 'S' ? 2 : 6);
        if (auto v = read_int(s)) {
            r.kind = ReplyKind::Resend;
            r.resend_line = *v;
            return r;
        }
    }
    if (line == "start") { r.kind = ReplyKind::Start; return r; }
    if (line == "wait") { r.kind = ReplyKind::Wait; return r; }
    if (starts_with_nocase(line, "echo:busy") || starts_with_nocase(line, "busy:")) { r.kind = ReplyKind::Busy; return r; }
    if (contains(line, "kill()") || contains(line, "Printer halted") || contains(line, "Printer stopped")) {
        r.kind = ReplyKind::Halted;
        return r;
    }
    if (starts_with_nocase(line, "error:")) {
        r.kind = (contains(line, "checksum") || contains(line, "Line Number") || contains(line, "Checksum"))
                     ? ReplyKind::LineError : ReplyKind::Error;
        return r;
    }
    return r;
}

}  // namespace xlate5::proto
