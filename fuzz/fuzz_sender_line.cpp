// SPDX-License-Identifier: GPL-3.0-or-later
// Fuzz target: the sender line parser, as xlate5's sender side and the virtual printer run it:
// each input line through the line checker (Marlin's order: number, then checksum; M110), and
// the text functions the session calls on what it takes. Stage: test harness; may call
// line_checker and line_protocol.
//
// Input: byte 0 bit 0: strict about a checksum without a number (the sender side); the rest is
// lines. Besides the sanitizers, a finding is a broken promise of the checker: a line starting
// with N taken without its number, a number taken that is not the last one + 1 (M110 aside), a
// last line outside +-kMaxLineNumber.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "daemon/line_checker.hpp"
#include "daemon/line_protocol.hpp"

using namespace xlate5;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 1) return 0;
    proto::LineChecker checker((data[0] & 1u) != 0);
    const std::string_view text(reinterpret_cast<const char*>(data + 1), size - 1);
    for (std::size_t pos = 0; pos <= text.size();) {
        std::size_t end = text.find('\n', pos);
        if (end == std::string_view::npos) end = text.size();
        const std::string_view line = text.substr(pos, end - pos);
        pos = end + 1;

        const std::int64_t before = checker.last_line();
        const auto v = checker.check(line);
        const std::int64_t after = checker.last_line();
        if (after < -proto::kMaxLineNumber || after > proto::kMaxLineNumber) std::abort();
        if (v.verdict != proto::LineChecker::Verdict::Take) {
            if (after != before) std::abort();  // a refused or repeated line changes nothing
            (void)checker.error_line(v.why);
            (void)checker.resend_line();
            continue;
        }
        std::string_view trimmed = line;
        while (!trimmed.empty() && (trimmed.front() == ' ' || trimmed.front() == '\t' || trimmed.front() == '\r')) trimmed.remove_prefix(1);
        if (!trimmed.empty() && trimmed.front() == 'N' && !v.number) std::abort();  // "N;0151 G1 …" run as "N"
        const std::string bare = proto::strip_comment(v.command);
        const auto code = proto::command_code(bare);
        if (v.number && !code.is('M', 110) && *v.number != before + 1) std::abort();
        if (code.is('M', 110))
            if (const auto n = proto::m110_line(bare)) (void)checker.set_last_line(*n);  // as the sender side does
        if (v.number) {
            // What the firmware side writes for a taken command reads back as the same line.
            const std::string again = proto::numbered(*v.number, bare);
            const auto r = proto::parse_received(again);
            if (!r.number || *r.number != *v.number || !r.checksum_ok) std::abort();
        }
    }
    return 0;
}
