// SPDX-License-Identifier: GPL-3.0-or-later
// The report's events: what the translation did near poles and limits (pole crossings, half
// turns, unwinds, branch changes, re-zeros), per-joint travel and ranges, and what the collision
// check found. Counts stay exact; the lists keep the first kMaxReportMarks (memory bounded).
// Parts of DeviationReport (report.hpp).
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace xlate5 {

inline constexpr std::size_t kMaxReportMarks = 2000;

// Where the counted events happened: each at the input line of its move and at the output's
// move lines (the emitter's count once the move was written), so a preview of the output marks
// exactly what is counted here.
class EventLog {
public:
    // A rotary turning by kHalfTurnDeg or more within a move is a half turn of the table or head;
    // a printing move turning one more than kPrintingTurnDeg is counted too.
    static constexpr double kHalfTurnDeg = 150;
    static constexpr double kPrintingTurnDeg = 90;
    enum class MarkKind { PoleCrossing, Unwind, BranchChange, Rezero };
    struct Mark {
        MarkKind kind;
        std::uint64_t line;
        std::uint64_t moves_written;
    };
    // How a move went near a pole: it changed branch across it (a pole crossing), and whether
    // it made a half turn (or a printing turn).
    void add_route(int pole_crossings, bool half_turn, bool printing_turn = false) {
        pole_crossings_ += std::uint64_t(pole_crossings), half_turns_ += half_turn, printing_turns_ += printing_turn;
    }
    // Whether a move ended on another solution of its pose (another turn, the other branch).
    void add_solution_change(int turns, int branch) { turns_ += std::uint64_t(turns), branches_ += std::uint64_t(branch); }
    void add_marks(std::uint64_t line, std::uint64_t moves_written, int pole_crossings, int change, int rezeros);

    const std::vector<Mark>& marks() const { return marks_; }
    std::uint64_t pole_crossings() const { return pole_crossings_; }
    std::uint64_t half_turns() const { return half_turns_; }
    std::uint64_t printing_turns() const { return printing_turns_; }
    std::uint64_t unwinds() const { return turns_; }
    std::uint64_t branch_changes() const { return branches_; }
    std::uint64_t rezeros() const { return rezeros_; }

private:
    std::uint64_t pole_crossings_ = 0, half_turns_ = 0, printing_turns_ = 0, turns_ = 0, branches_ = 0, rezeros_ = 0;
    std::vector<Mark> marks_;
};

// Where each joint went over the file: its rotary travel, its extremes, and the least rotary
// travel any plan could have (the planner's bound, see planner.cpp).
class JointTotals {
public:
    struct Range {
        char joint;
        double low, high;
    };
    void add_travel(char joint, double degrees);
    void add_range(char joint, double low, double high);
    void set_rotary_bound(double degrees) { rotary_bound_ = degrees; }
    const std::vector<std::pair<char, double>>& travel() const { return travel_; }
    const std::vector<Range>& ranges() const { return ranges_; }
    double rotary_bound() const { return rotary_bound_; }  // negative: not computed

private:
    std::vector<std::pair<char, double>> travel_;  // one per rotary, in the order met
    std::vector<Range> ranges_;                    // one per joint
    double rotary_bound_ = -1;
};

// What the collision check found (it ran when the machine has bodies): collisions, and travels
// re-routed round a contact (lifted along the tool axis) instead of refused; each counted and
// listed ("line: message") and marked for the preview.
class CollisionLog {
public:
    // At the input line and the written move (from 0) of its piece, the bodies that meet (`other`
    // empty: the printed part, printed at `bead_line`) and the contact (part frame, mm).
    struct Mark {
        std::uint64_t line = 0, move = 0, bead_line = 0;
        std::string tool, other;
        std::array<double, 3> at{};
    };
    void set_checked() { checked_ = true; }
    bool checked() const { return checked_; }
    void add_collision(std::uint64_t line, const std::string& message) {
        ++collisions_.count;
        if (collisions_.list.size() < kMaxReportMarks) collisions_.list.push_back(std::to_string(line) + ": " + message);
    }
    void add_collision(std::uint64_t line, const std::string& message, Mark mark) {
        if (collisions_.marks.size() < kMaxReportMarks) collisions_.marks.push_back(std::move(mark));
        add_collision(line, message);
    }
    void add_reroute(std::uint64_t line, const std::string& message, Mark mark) {
        ++reroutes_.count;
        if (reroutes_.list.size() < kMaxReportMarks) reroutes_.list.push_back(std::to_string(line) + ": " + message);
        if (reroutes_.marks.size() < kMaxReportMarks) reroutes_.marks.push_back(std::move(mark));
    }
    // One kind of finding: its exact count, its first messages and marks.
    struct Found {
        std::uint64_t count = 0;
        std::vector<std::string> list;
        std::vector<Mark> marks;
    };
    const Found& collisions() const { return collisions_; }
    const Found& reroutes() const { return reroutes_; }

private:
    bool checked_ = false;
    Found collisions_, reroutes_;
};

}  // namespace xlate5
