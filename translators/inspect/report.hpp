// SPDX-License-Identifier: GPL-3.0-or-later
// The kinematic-error report: how far the firmware's joint-linear path leaves the programmed
// tool-space path, per file, so a user can inspect a file before printing it. Memory is bounded
// whatever the file size (histograms and a series that halves its resolution as it grows).
// Beside the stages: the planner logs each measured move into it. May call: nothing of the
// pipeline.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace xlate5 {

class DeviationReport {
public:
    DeviationReport(std::string file, std::string machine, double tolerance, double angle_tolerance);

    // One input move: its largest sampled tip (mm) and axis (degrees) deviation, its feed error
    // (relative: tip speed the firmware will produce over the programmed speed, minus 1), and
    // how many output moves it became.
    void add_move(std::uint64_t line, double tip, double angle, double feed_error, int pieces);
    void add_rotary_travel(char joint, double degrees);
    // How a move went near a pole: it changed branch across it (a pole crossing), and whether
    // a rotary turned by kHalfTurnDeg or more within it (a half turn of the table or head).
    void add_route(int pole_crossings, bool half_turn, bool printing_turn = false) {
        pole_crossings_ += std::uint64_t(pole_crossings), half_turns_ += half_turn, printing_turns_ += printing_turn;
    }
    static constexpr double kPrintingTurnDeg = 90;  // a printing move turning a rotary more than this is counted
    // The least rotary travel of any plan (the planner's bound, see planner.cpp): its figure and
    // the travel's ratio to it go into the JSON.
    void set_rotary_bound(double degrees) { rotary_bound_ = degrees; }
    static constexpr double kHalfTurnDeg = 150;
    // The rest of what a move did: where each joint went (its extremes over the move), how long
    // the firmware takes for it, and whether it ended on another solution of its pose.
    void add_joint_range(char joint, double low, double high);
    void add_time(double minutes) { minutes_ += minutes; }
    void add_solution_change(int turns, int branch) { turns_ += std::uint64_t(turns), branches_ += std::uint64_t(branch); }
    void set_lines(std::uint64_t in, std::uint64_t out) { lines_in_ = in, lines_out_ = out; }
    // The collision check ran (the machine has bodies): the report counts and lists what it found
    // (the first kMaxMarks, as "line: message"), under "collisions".
    void set_collision_checked() { collision_checked_ = true; }
    void add_collision(std::uint64_t line, const std::string& message) {
        ++collision_count_;
        if (collisions_.size() < kMaxMarks) collisions_.push_back(std::to_string(line) + ": " + message);
    }
    std::uint64_t collisions() const { return collision_count_; }
    // Where a collision was found, for the preview: at the input line and the written move (from
    // 0) of its piece, the bodies that meet (`other` empty: the printed part, printed at
    // `bead_line`) and the contact (part frame, mm). The first kMaxMarks are kept, as the list.
    struct CollisionMark {
        std::uint64_t line = 0, move = 0, bead_line = 0;
        std::string tool, other;
        std::array<double, 3> at{};
    };
    void add_collision(std::uint64_t line, const std::string& message, CollisionMark mark) {
        if (collision_marks_.size() < kMaxMarks) collision_marks_.push_back(std::move(mark));
        add_collision(line, message);
    }
    const std::vector<CollisionMark>& collision_marks() const { return collision_marks_; }
    // A travel the check re-routed round a contact (lifted along the tool axis) instead of
    // refusing it: counted and listed under "rerouted", marked as a collision is.
    void add_reroute(std::uint64_t line, const std::string& message, CollisionMark mark) {
        ++reroute_count_;
        if (reroutes_.size() < kMaxMarks) reroutes_.push_back(std::to_string(line) + ": " + message);
        if (reroute_marks_.size() < kMaxMarks) reroute_marks_.push_back(std::move(mark));
    }
    std::uint64_t reroutes() const { return reroute_count_; }
    const std::vector<CollisionMark>& reroute_marks() const { return reroute_marks_; }

    // Where the counted events happened: each at the input line of its move and at the output's
    // move lines (the emitter's count once the move was written), so a preview of the output
    // marks exactly what is counted here. The first kMaxMarks are kept; the counts stay exact.
    enum class MarkKind { PoleCrossing, Unwind, BranchChange, Rezero };
    struct Mark {
        MarkKind kind;
        std::uint64_t line;
        std::uint64_t moves_written;
    };
    static constexpr std::size_t kMaxMarks = 2000;
    void add_marks(std::uint64_t line, std::uint64_t moves_written, int pole_crossings, int change, int rezeros);
    const std::vector<Mark>& marks() const { return marks_; }
    std::uint64_t pole_crossings() const { return pole_crossings_; }
    std::uint64_t unwinds() const { return turns_; }
    std::uint64_t branch_changes() const { return branches_; }
    std::uint64_t output_moves() const { return pieces_; }
    std::uint64_t rezeros() const { return rezeros_; }

    // Members an observer of the written output adds to json() (the preview's scan: what only the
    // written lines tell), each line "  \"name\": value,\n".
    void set_written(std::string members) { written_ = std::move(members); }
    std::string json() const;
    std::string svg() const;

    double max_tip() const { return tip_.max; }
    std::uint64_t worst_tip_line() const { return tip_.max_line; }

private:
    // Counts in logarithmic bins (1e-7 .. 1e3), for percentiles without keeping every value.
    struct Distribution {
        static constexpr int kBins = 200;
        std::array<std::uint64_t, kBins> bins{};
        std::uint64_t count = 0, zeros = 0;
        double max = 0, sum = 0;
        std::uint64_t max_line = 0;
        void add(double v, std::uint64_t line);
        double percentile(double p) const;
        std::string json() const;
    };
    struct Point {
        std::uint64_t first_line, last_line;
        double tip, angle;
    };

    std::string file_, machine_;
    double tolerance_, angle_tolerance_;
    std::uint64_t lines_in_ = 0, lines_out_ = 0, moves_ = 0, split_moves_ = 0, pieces_ = 0, pole_crossings_ = 0, half_turns_ = 0, printing_turns_ = 0;
    double rotary_bound_ = -1;  // not computed
    Distribution tip_, angle_, feed_;
    std::vector<std::pair<char, double>> travel_;
    struct Range {
        char joint;
        double low, high;
    };
    std::vector<Range> ranges_;  // one per joint
    double minutes_ = 0;
    std::uint64_t turns_ = 0, branches_ = 0, rezeros_ = 0;
    std::vector<Mark> marks_;
    std::string written_;
    bool collision_checked_ = false;
    std::uint64_t collision_count_ = 0;
    std::vector<std::string> collisions_;
    std::vector<CollisionMark> collision_marks_;
    std::uint64_t reroute_count_ = 0;
    std::vector<std::string> reroutes_;
    std::vector<CollisionMark> reroute_marks_;
    std::vector<Point> series_;  // at most kMaxPoints, each the worst of `bucket_` moves
    std::uint64_t bucket_ = 1, in_bucket_ = 0;
    static constexpr std::size_t kMaxPoints = 2000;
};

struct Machine;
struct MoveResult;

// Measured moves on their way to the report: added at once, or, while the look-back holds the
// output they belong to (at least their own line's), held and released with it (dropped when it
// translates them again or refuses their line).
class MoveLog {
public:
    MoveLog(DeviationReport& report, const Machine& machine) : report_(report), machine_(machine) {}

    void hold(bool on) { hold_ = on; }
    void set_rotary_bound(double degrees) { report_.set_rotary_bound(degrees); }
    void add(std::uint64_t line, const MoveResult& m);
    // G92s that re-zeroed a rotary after a move that is not measured (a joint move before the
    // program placed the tip): counted and marked like a measured move's.
    void add_rezeros(std::uint64_t line, std::uint64_t moves_written, int rezeros);

    // A held move, and the rotary travel of the held moves (each move's ends at travel_end).
    struct Pending {
        std::uint64_t line;
        double tip, angle, feed;
        int pieces;
        std::size_t travel_end;
        double minutes;
        int change;  // SolutionChange
        int pole_crossings;
        bool half_turn;
        int rezeros;
        bool printing_turn;
        std::uint64_t moves_written;
        bool measured;  // false: only its re-zeros (add_rezeros)
    };
    struct Held {
        std::vector<Pending> moves;
        std::vector<std::pair<char, double>> travel;
        std::vector<double> ranges;  // per held move, low and high of every joint
    };
    std::size_t held_count() const { return held_.moves.size(); }
    void release(std::size_t moves);  // the first `moves` held moves go to the report
    const Held& held() const { return held_; }
    void set_held(const Held& h) { held_ = h; }
    void drop_held() {
        held_.moves.clear();
        held_.travel.clear();
        held_.ranges.clear();
    }
    // The held moves from the `moves`-th on are dropped: a refused line's, whose output is dropped.
    void drop_held_from(std::size_t moves);

private:
    void add_rest(const double* ranges, double minutes, int change);  // ranges: low, high of every joint
    DeviationReport& report_;
    const Machine& machine_;
    bool hold_ = false;
    Held held_;
    std::vector<double> ranges_;  // scratch: one move's low and high of every joint
};

}  // namespace xlate5
