// SPDX-License-Identifier: GPL-3.0-or-later
// The look-back, over the interpreter and planner: holds the output from the latest travel move
// on (for at most `lines` input lines), so that when a printing move further on would take a
// bounded rotary past its limit, that travel move can be translated again ending on another
// solution of its pose (the other branch or another turn) and the printed path stays continuous.
// It holds the window's lines as interpreted commands (commands.hpp: values) and one copy of the
// stages' state, taken before the window's first line: a replay runs the commands again from that
// copy through the planner onward; the interpreter is not run again. No line copies the whole
// state: the modal state is kept by assignment (a few bytes), and only a line that may travel
// (the next window's first) copies the stages' state before it runs. A refused line is undone
// from that copy, or else from the window's copy and a quiet replay of the lines since: only a
// refused line pays. Outside a window the lines since the copy are kept the same way, a few.
// May call: the forward stages (to interpret a line, run its commands, or the window's again) and
// the move log.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "translators/pipeline/collide.hpp"
#include "translators/pipeline/commands.hpp"
#include "translators/pipeline/emitter.hpp"
#include "translators/pipeline/interpreter.hpp"
#include "translators/pipeline/planner.hpp"
#include "translators/inspect/report.hpp"

namespace xlate5 {

// What running a line's commands changes: the planner's state, the collision stage's place in the
// printed part and what the emitter remembers of the firmware. Plain values: a copy is the state.
struct StageState {
    explicit StageState(const Machine& machine) : emitter(machine) {}
    PlannerState planner;
    CollideCursor collide;
    JointEmitter emitter;
};

// Everything a line of the forward direction can change: the interpreter's modal state (a
// replay of commands leaves it as it is) and the stages'.
struct ForwardState {
    explicit ForwardState(const Machine& machine) : stages(machine) {}
    ModalState modal;
    StageState stages;
};

// One input line as the look-back holds it: its text (the commands' passed numbers are views into
// it) and its commands. Held by pointer: the views stay valid while the window's list grows.
struct HeldLine {
    std::string text;
    std::uint64_t line_no = 0;
    bool text_argument = false;  // its command takes its text whole (fit_marlin_lines)
    bool e_relative = false;     // M83 after it was read (the collision stage's E)
    cmd::CommandList commands;
};

// The forward stages as the look-back runs them, one input line at a time (translator.cpp wires
// them).
class LineStages {
public:
    // Reads `line` (without '\n') into `held` (its text and commands); the modal state changes
    // with it. Returns whether running the commands may make a travel move (LineRun::travels)
    // from the state as it is: errs on the side of yes, never of no. Throws InputError naming the
    // file, line (run.line_no) and column: the modal state is then the caller's to restore, the
    // stages' is unchanged.
    virtual bool interpret(std::string_view line, const LineRun& run, HeldLine& held) = 0;
    // Runs a line's commands, appending its output to `out`. Throws InputError naming the file,
    // line and column: its output is then taken back, the stages' state is the caller's to restore.
    virtual void run(const HeldLine& held, LineRun& run, std::string& out) = 0;
    // The firmware's position is no longer exactly known (a refused line without look-back).
    virtual void position_unknown() = 0;
    // While quiet, collisions are not told (a replay of lines already told).
    virtual void set_quiet(bool quiet) = 0;

protected:
    ~LineStages() = default;
};

class LookBack {
public:
    // Memory stays bounded by bytes as well as by lines (docs/limits.md): past either bound the
    // window closes (what it held is final, as past `lines`): the input text held (with its
    // commands), and the output held back.
    static constexpr std::size_t kMaxWindowBytes = std::size_t(1) << 20;
    static constexpr std::size_t kMaxHeldBytes = std::size_t(8) << 20;
    // Outside a window the lines since the stages' copy are kept too (a refused line is undone
    // by replaying them): at most this many, then the copy is taken again.
    static constexpr std::size_t kMaxUndoLines = 64;
    // End solutions of a travel move tried in turn (nearest first) before a line is refused.
    static constexpr int kMaxCandidates = 64;
    // With each, the window's branch choices near a pole (PoleChoices) taken the other way one
    // more at a time: the window is translated again at most this many times, then as many again
    // with a half turn in place allowed near the pole (PoleChoices::turns), before a line is
    // refused.
    static constexpr int kMaxReplays = 256;

    // `log` may be null (no report). Call restart() once the stages are wired.
    LookBack(LineStages& stages, ForwardState& state, MoveLog* log);

    // 0 (the default): every line's output is appended at once, and only the travel move that
    // itself runs into a limit unwinds. With look-back on, call finish() after the last line.
    // `candidates` (1 to kMaxCandidates) may lower the solutions tried.
    void set_lines(std::size_t lines, int candidates = kMaxCandidates);
    void feed(std::string_view line, std::uint64_t line_no, std::string& out);
    void finish(std::string& out);
    // Whether a window is open (output held, or a travel move that may yet be translated again):
    // false, finish() would release nothing and change nothing.
    bool holding() const { return win_.checkpoint || !held_.empty(); }
    // The state was changed between lines (not holding()): the stages' copy is taken again.
    void restart();

private:
    void feed_alone(HeldLine& current, std::uint64_t line_no, std::string& out);
    std::string refusal_advice(bool linear, bool had_checkpoint) const;
    bool unwind_before(HeldLine& current, std::uint64_t line_no, LineRun& last);
    bool replay(int candidate, const PoleChoices& flips, HeldLine& current, std::uint64_t line_no, LineRun& last,
                bool& missing);
    void undo_line(bool copied);
    void start_window(std::uint64_t line_no, int choices);
    void release(std::size_t bytes, std::size_t moves, std::string& out);
    // The slot the next line is read into (its text and commands reuse the slot's memory).
    HeldLine& next_line() {
        if (win_.size == win_.lines.size()) [[unlikely]]
            win_.lines.push_back(std::make_unique<HeldLine>());
        return *win_.lines[win_.size];
    }
    std::size_t held_moves() const { return log_ ? log_->held_count() : 0; }

    LineStages& stages_;
    ForwardState& state_;
    MoveLog* log_;
    std::size_t lines_ = 0;
    int candidates_ = kMaxCandidates;
    // The modal state before the current line (assigned, not constructed: the tilted plane is
    // copied only when it changed).
    ModalState modal_;
    // The lines from the stages' copy on, and what a replay of them needs.
    struct Window {
        explicit Window(const StageState& state) : from(state) {}
        StageState from;  // the stages' state before the first line
        // The lines in their order: the first `size`; the rest are kept for reuse.
        std::vector<std::unique_ptr<HeldLine>> lines;
        std::size_t size = 0;
        std::size_t bytes = 0;    // their text
        bool checkpoint = false;  // the first is a travel move's line, that may end on another solution
        std::uint64_t checkpoint_line = 0;
        int chosen = -1;    // the solution the checkpoint's travel move took (-1: its usual end)
        PoleChoices flips;  // the window's branch choices near a pole taken the other way (a replay)
        int choices = 0;    // the window's branch choices so far
    } win_;
    StageState before_;   // the stages' state before the current line, when it may travel (the next from)
    std::string held_;    // the window's output, not yet released
    std::string scratch_; // a quiet replay's output
};

}  // namespace xlate5
