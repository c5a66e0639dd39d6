// SPDX-License-Identifier: GPL-3.0-or-later
// The look-back, over the interpreter and planner: holds the output from the latest travel move
// on (for at most `lines` input lines), so that when a printing move further on would take a
// bounded rotary past its limit, that travel move can be translated again ending on another
// solution of its pose (the other branch or another turn) and the printed path stays continuous.
// Its checkpoint is one snapshot of everything a line can change, copied whole.
// May call: the forward stages (to translate a line, or a window of them again) and the move log.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "translators/pipeline/collide.hpp"
#include "translators/pipeline/emitter.hpp"
#include "translators/pipeline/interpreter.hpp"
#include "translators/pipeline/planner.hpp"
#include "translators/inspect/report.hpp"

namespace xlate5 {

// The state a line can change above the emitter: rolled back as one when a line fails.
struct LineState {
    ModalState modal;
    PlannerState planner;
    CollideCursor collide;  // the collision stage's place in the printed part: rolled back with the line
};

// Everything a line of the forward direction can change: the interpreter's and the planner's
// state and what the emitter remembers of the firmware.
struct ForwardState {
    explicit ForwardState(const Machine& machine) : emitter(machine) {}
    LineState line;
    JointEmitter emitter;
};

// The forward stages as the look-back runs them, one input line at a time (translator.cpp wires
// them).
class LineStages {
public:
    // Translates one line (without '\n'), appending its output to `out`. Throws InputError naming
    // the file, line (run.line_no) and column; the state is then as before the line and the
    // firmware's position is taken as unknown. `before`, when given, is the caller's own copy of
    // the state as it is now (the look-back takes one of every line): the line is undone from it
    // instead of from a second copy.
    virtual void feed_line(std::string_view line, LineRun& run, std::string& out, const LineState* before = nullptr) = 0;

protected:
    ~LineStages() = default;
};

class LookBack {
public:
    // Memory stays bounded by bytes as well as by lines (docs/limits.md): past either bound the
    // window closes (what it held is final, as past `lines`): the input text a replay needs,
    // and the output held back.
    static constexpr std::size_t kMaxWindowBytes = std::size_t(1) << 20;
    static constexpr std::size_t kMaxHeldBytes = std::size_t(8) << 20;
    // End solutions of a travel move tried in turn (nearest first) before a line is refused.
    static constexpr int kMaxCandidates = 64;
    // With each, the window's branch choices near a pole (PoleChoices) taken the other way one
    // more at a time: the window is translated again at most this many times, then as many again
    // with a half turn in place allowed near the pole (PoleChoices::turns), before a line is
    // refused.
    static constexpr int kMaxReplays = 256;

    // `log` may be null (no report).
    LookBack(LineStages& stages, ForwardState& state, MoveLog* log);

    // 0 (the default): every line's output is appended at once, and only the travel move that
    // itself runs into a limit unwinds. With look-back on, call finish() after the last line.
    // `candidates` (1 to kMaxCandidates) may lower the solutions tried.
    void set_lines(std::size_t lines, int candidates = kMaxCandidates);
    void feed(std::string_view line, std::uint64_t line_no, std::string& out);
    void finish(std::string& out);
    // Whether a window is open (output held, or a travel move that may yet be translated again):
    // false, finish() would release nothing and change nothing.
    bool holding() const { return have_checkpoint_ || !held_.empty(); }

private:
    void feed_alone(std::string_view line, std::uint64_t line_no, std::string& out);
    std::string refusal_advice(bool linear, bool had_checkpoint) const;
    bool unwind_before(std::string_view line, std::uint64_t line_no, LineRun& last);
    bool replay(int candidate, const PoleChoices& flips, std::string_view line, std::uint64_t line_no, LineRun& last,
                bool& missing);
    void release(std::size_t bytes, std::size_t moves, std::string& out);
    std::size_t held_moves() const { return log_ ? log_->held_count() : 0; }

    LineStages& stages_;
    ForwardState& state_;
    MoveLog* log_;
    std::size_t lines_ = 0;
    int candidates_ = kMaxCandidates;
    bool have_checkpoint_ = false;
    std::uint64_t checkpoint_line_ = 0;
    int chosen_ = -1;  // the solution the checkpoint's travel move took (-1: its usual end)
    PoleChoices flips_;   // the window's branch choices near a pole taken the other way (a replay)
    int choices_ = 0;     // the window's branch choices so far
    ForwardState before_line_, checkpoint_;
    std::string window_text_;  // input lines from the checkpoint's travel move on, '\n'-separated
    std::vector<std::uint64_t> window_lines_;
    std::string held_;         // their output, not yet released
};

}  // namespace xlate5
