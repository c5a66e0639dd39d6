// SPDX-License-Identifier: GPL-3.0-or-later
// The report's events and joint totals. What it may call: see report_events.hpp.
#include "translators/inspect/report_events.hpp"

#include <algorithm>

#include "translators/pipeline/motion.hpp"

namespace xlate5 {

void EventLog::add_marks(std::uint64_t line, std::uint64_t moves_written, int pole_crossings, int change, int rezeros) {
    rezeros_ += std::uint64_t(std::max(rezeros, 0));
    const auto keep = [&](MarkKind kind, int times) {
        for (int i = 0; i < times && marks_.size() < kMaxReportMarks; ++i) marks_.push_back({kind, line, moves_written});
    };
    keep(MarkKind::PoleCrossing, pole_crossings);
    keep(MarkKind::Unwind, change == int(SolutionChange::Turns));
    keep(MarkKind::BranchChange, change == int(SolutionChange::Branch));
    keep(MarkKind::Rezero, rezeros);
}

void JointTotals::add_travel(char joint, double degrees) {
    for (auto& [j, d] : travel_)
        if (j == joint) {
            d += degrees;
            return;
        }
    travel_.emplace_back(joint, degrees);
}

void JointTotals::add_range(char joint, double low, double high) {
    for (auto& r : ranges_)
        if (r.joint == joint) {
            r.low = std::min(r.low, low);
            r.high = std::max(r.high, high);
            return;
        }
    ranges_.push_back({joint, low, high});
}

}  // namespace xlate5
