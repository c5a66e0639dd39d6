// SPDX-License-Identifier: GPL-3.0-or-later
// Fuzz target: the firmware reply classifier (ok with ADVANCED_OK fields, Resend, busy, start,
// halts, line errors), line by line. Stage: test harness; may call line_protocol.
//
// Input: lines as a firmware would send them. Besides the sanitizers, a finding is an ok whose
// payload is not part of its line.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "daemon/line_protocol.hpp"

using namespace xlate5;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    for (std::size_t pos = 0; pos <= text.size();) {
        std::size_t end = text.find('\n', pos);
        if (end == std::string_view::npos) end = text.size();
        const std::string_view line = text.substr(pos, end - pos);
        pos = end + 1;
        const auto r = proto::classify(line);
        if (r.kind == proto::ReplyKind::Ok) {
            // The payload is a view into the line (no copy, no dangling).
            if (r.payload.data() < line.data() || r.payload.data() + r.payload.size() > line.data() + line.size()) std::abort();
        }
    }
    return 0;
}
