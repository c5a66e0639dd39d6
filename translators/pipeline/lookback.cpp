// SPDX-License-Identifier: GPL-3.0-or-later
// The look-back over the interpreter and planner: held output, checkpoint, replay.
// What it may call: see lookback.hpp.
#include "translators/pipeline/lookback.hpp"

#include <stdexcept>
#include <utility>

#include "translators/error.hpp"

namespace xlate5 {

LookBack::LookBack(LineStages& stages, ForwardState& state, MoveLog* log)
    : stages_(stages), state_(state), log_(log), win_(state.stages), before_(state.stages) {
    // Moves are held, with look-back or not, at least for their line: a refused line's are dropped with its output.
    if (log_) log_->hold(true);
}

void LookBack::restart() {
    win_.from = state_.stages;
    win_.size = 0;
    win_.bytes = 0;
}

namespace {
// A linear joint past its travel is a placement, not a turn: no travel move fixes it.
std::string linear_limit_advice() {
    return "; the part lies outside the machine's travel there: the slicer's origin (a corner or the middle of its bed) is "
           "not where the machine's is, or the part is too large. Place the part in the slicer so that its moves stay within "
           "the machine file's limits (xlate5 --machine NAME pose shows where the tip is for given joints), or set the limits "
           "to the machine's real travel";
}
// A joint the machine does not have: no placement or turn helps.
std::string absent_limit_advice() {
    return "; no placement of the part changes that: this machine cannot tilt the tool to the axis the program asks for "
           "there (slice or plan the part for this machine's axes)";
}
}  // namespace

void LookBack::set_lines(std::size_t lines, int candidates) {
    lines_ = lines;
    candidates_ = candidates < 1 ? 1 : candidates > kMaxCandidates ? kMaxCandidates : candidates;
}

// Without look-back: the line's output goes out at once; only a travel move that itself runs
// into a limit unwinds (the planner tries its other ends).
void LookBack::feed_alone(HeldLine& current, std::uint64_t line_no, std::string& out) {
    LineRun run;
    run.line_no = line_no;
    const std::size_t moves_start = held_moves();
    try {
        stages_.run(current, run, out);
    } catch (const InputError& e) {
        if (log_) log_->drop_held_from(moves_start);
        // The line's state is undone, but the emitter keeps what it took the firmware to be told,
        // the position then unknown (the firmware may have run part of the line).
        const JointEmitter told = state_.stages.emitter;
        undo_line(false);
        state_.stages.emitter = told;
        stages_.position_unknown();
        if (!run.hit_limit) throw;
        throw InputError(e.file(), e.line(), e.column(),
                         e.message() + (run.absent_limit   ? absent_limit_advice()
                                        : run.linear_limit ? linear_limit_advice()
                                                           : "; turn the joint back on a travel move before this line, or plan the path "
                                                             "within the limits"));
    }
    if (log_) log_->release(held_moves());
    if (++win_.size >= kMaxUndoLines) restart();
}

// What a line refused on a joint limit is told to do, after the limit's own message.
std::string LookBack::refusal_advice(bool linear, bool had_checkpoint) const {
    if (linear) return linear_limit_advice();
    if (had_checkpoint)
        return "; turning it back on the travel move at line " + std::to_string(win_.checkpoint_line) +
               " does not keep the printing from there to here within the limits: add a travel move (G0, or G1 "
               "without E) nearer this line, where the joint can turn back, or plan the path within the limits";
    return "; there is no travel move (G0, or G1 without E) within the " + std::to_string(lines_) +
           " lines before this one to turn the joint back on: add one before this line, or plan the path "
           "within the limits";
}

void LookBack::feed(std::string_view line, std::uint64_t line_no, std::string& out) {
    HeldLine& current = next_line();
    LineRun run;
    run.line_no = line_no;
    modal_ = state_.modal;  // the interpreter's undo: a few bytes (the plane by its stamp)
    bool copied = false;
    try {
        copied = stages_.interpret(line, run, current);
    } catch (const InputError&) {
        state_.modal = modal_;
        throw;
    }
    if (lines_ == 0) return feed_alone(current, line_no, out);
    // A line that may travel may start the next window: the stages' state before it is kept.
    if (copied) before_ = state_.stages;
    // With no window open nothing is held (held_ is empty): the line's output goes straight to
    // `out`, where only a travel move's has to be taken back into held_ (below). One copy of the
    // output fewer on most lines.
    const bool direct = !win_.checkpoint;
    std::string& to = direct ? out : held_;
    const std::size_t held_start = to.size(), moves_start = held_moves();
    run.pole.seen = win_.checkpoint ? win_.choices : 0;
    const int seen_before = run.pole.seen;
    try {
        stages_.run(current, run, to);
    } catch (const InputError& e) {
        // A refused line (the service goes on after one typed in a terminal) leaves nothing
        // behind: its output was only held, so what the emitter remembers of the firmware is
        // restored too, the report forgets its moves (an arc's chords before the one refused),
        // and later lines print as if it never came. One on a limit is refused only when the
        // window cannot be translated again to fit it (without a window unwind_before refuses at
        // once, so `to` is still the one written to).
        const bool limit = run.hit_limit, had_checkpoint = win_.checkpoint, linear = run.linear_limit, absent = run.absent_limit;
        // A pole that no way within the tolerance passes may be one an earlier branch choice
        // near it led into (coarse loops round a bounded turning joint's pole): tried again too.
        if (!(limit || (run.at_pole && run.pole.seen > 0)) || !unwind_before(current, line_no, run)) {
            to.resize(held_start);
            if (log_) log_->drop_held_from(moves_start);
            undo_line(copied);
            if (!limit) throw;
            throw InputError(e.file(), e.line(), e.column(), e.message() + (absent ? absent_limit_advice() : refusal_advice(linear, had_checkpoint)));
        }
    }
    if (direct && run.travels) {
        // The travel move's own output starts the window: held, not yet final.
        held_.assign(out, held_start, std::string::npos);
        out.resize(held_start);
    }
    if (run.travels) {
        // A travel move: the next checkpoint. What came before it is final.
        if (!copied) throw std::logic_error("the look-back kept no state before a travel move");
        release(direct ? 0 : held_start, moves_start, out);
        start_window(line_no, run.pole.seen - seen_before);  // the travel line's own choices start the window's count
    } else {
        if (win_.checkpoint) win_.choices = run.pole.seen;
        ++win_.size;
        win_.bytes += current.text.size() + 1;
    }
    if (!win_.checkpoint && held_.empty()) {
        // No window open (most lines without travel moves): nothing is held; only the report's
        // moves of this line are final. The lines kept to undo a refused one stay few.
        if (log_) log_->release(held_moves());
        if (win_.size >= kMaxUndoLines) restart();
        return;
    }
    // Memory stays bounded: past the window (in lines or in bytes) the held lines are final.
    if (!win_.checkpoint || win_.size > lines_ || win_.bytes > kMaxWindowBytes || held_.size() > kMaxHeldBytes) {
        release(held_.size(), held_moves(), out);
        win_.checkpoint = false;
        restart();
    }
}

// The current line (a travel move's) starts the window, from the state before it (kept: a line
// that travels is one that may), `choices` its branch choices near a pole.
void LookBack::start_window(std::uint64_t line_no, int choices) {
    std::swap(win_.from, before_);
    win_.checkpoint = true;
    win_.checkpoint_line = line_no;
    win_.chosen = -1;
    win_.flips = PoleChoices{};
    win_.choices = choices;
    std::swap(win_.lines[0], win_.lines[win_.size]);
    win_.size = 1;
    win_.bytes = win_.lines[0]->text.size() + 1;
}

void LookBack::finish(std::string& out) {
    release(held_.size(), held_moves(), out);
    win_.checkpoint = false;
    restart();
}

// A refused line leaves the state as before it: the modal state from its copy, the
// stages' from the copy taken before the line when it may travel, else from the window's start
// and a quiet replay of the lines since (their output, moves and collisions already told).
void LookBack::undo_line(bool copied) {
    state_.modal = modal_;
    if (copied) {
        state_.stages = before_;
        return;
    }
    state_.stages = win_.from;
    if (win_.size == 0) return;
    const MoveLog::Held kept = log_ ? log_->held() : MoveLog::Held{};
    struct Quiet {
        LineStages& stages;
        explicit Quiet(LineStages& s) : stages(s) { stages.set_quiet(true); }
        ~Quiet() { stages.set_quiet(false); }
    } quiet(stages_);
    PoleChoices pole = win_.checkpoint ? win_.flips : PoleChoices{};
    pole.seen = 0;
    for (std::size_t i = 0; i < win_.size; ++i) {
        LineRun run;
        run.line_no = win_.lines[i]->line_no;
        run.pole = pole;
        if (i == 0 && win_.checkpoint) run.end_candidate = win_.chosen;
        scratch_.clear();
        stages_.run(*win_.lines[i], run, scratch_);  // as when it was first run: it cannot fail
        pole.seen = run.pole.seen;
    }
    if (log_) log_->set_held(kept);
}

// The line at line_no runs a joint past its limit: translate the window again from the
// checkpoint, its travel move ending on each other solution of its pose in turn (nearest
// first), until the window and this line fit. On failure everything is as before.
bool LookBack::unwind_before(HeldLine& current, std::uint64_t line_no, LineRun& last) {
    if (!win_.checkpoint || win_.size == 0) return false;
    const std::string held_saved = held_;
    const MoveLog::Held log_saved = log_ ? log_->held() : MoveLog::Held{};
    const int was = win_.chosen;
    // The travel move's ends in turn, the one it took first (its choices so far kept), then the
    // others. With each, as it is, then with one more branch choice near a pole taken the other
    // way: which branch a printed loop needs where it passes a bounded turning joint's pole can
    // depend on where it goes long after. At most kMaxReplays translations of the window.
    // Then all of that again with a flipped choice allowed a half turn in place where its move
    // passes nearest the pole (PoleChoices::turns): the last resort, each pass within kMaxReplays.
    const int first_choices = last.pole.seen;
    // Last, with longer moves held near the pole as well (PoleChoices::wide), for a line that
    // failed on a rotary's limit or at a pole (a linear joint's is a placement no hold changes).
    const int passes = last.linear_limit ? 2 : 3;
    for (int pass = 0; pass < passes; ++pass) {
        const bool turns = pass > 0, wide = pass == 2;
        int replays = 0;
        bool missing = false;
        last.pole.seen = first_choices;
        for (int k = -1; k < candidates_ && !missing && replays < kMaxReplays; ++k) {
            const bool taken = k < 0;  // first the end taken (-1 its usual one), then the others
            if (!taken && k == was) continue;
            const int candidate = taken ? was : k;
            PoleChoices base = taken ? win_.flips : PoleChoices{};
            base.turns = turns;
            base.wide = wide;
            // The end as it is (tried already, for the end taken, by the line's own translation).
            int choices = last.pole.seen;  // the choices up to where the line failed
            // (With turns, the end taken with its flips is another translation than the line's own.)
            if (!taken || (turns && base.n_flips > 0) || wide) {
                ++replays;
                if (replay(candidate, base, current, line_no, last, missing)) {
                    win_.chosen = candidate;
                    win_.flips = base;
                    return true;
                }
                if (missing) break;
                choices = last.pole.seen;
            }
            if (base.n_flips >= PoleChoices::kMaxFlips) continue;
            for (int d = 0; d < choices && replays < kMaxReplays; ++d) {
                bool taken = false;
                for (int i = 0; i < base.n_flips; ++i) taken = taken || base.flips[i] == d;
                if (taken) continue;
                PoleChoices flips = base;
                flips.flips[flips.n_flips++] = d;
                bool none = false;
                ++replays;
                if (replay(candidate, flips, current, line_no, last, none)) {
                    win_.chosen = candidate;
                    win_.flips = flips;
                    return true;
                }
            }
        }
    }
    // The stages' state is the caller's to restore (undo_line).
    held_ = held_saved;
    if (log_) log_->set_held(log_saved);
    return false;
}

// The window's commands run again from the checkpoint, its travel move ending on solution
// `candidate` (-1: its usual end) and the branch choices in `flips` taken the other way, then the
// line's: true when all of it fits. `missing`: there is no solution `candidate`.
bool LookBack::replay(int candidate, const PoleChoices& flips, HeldLine& current, std::uint64_t line_no, LineRun& last,
                      bool& missing) {
    state_.stages = win_.from;
    held_.clear();
    if (log_) log_->drop_held();
    PoleChoices pole = flips;
    pole.seen = 0;
    try {
        for (std::size_t i = 0; i < win_.size; ++i) {
            LineRun run;
            run.line_no = win_.lines[i]->line_no;
            run.pole = pole;
            if (i == 0) run.end_candidate = candidate;  // the checkpoint's travel move ends on this solution
            try {
                stages_.run(*win_.lines[i], run, held_);
            } catch (const InputError&) {
                missing = run.candidate_missing;
                throw;
            }
            pole.seen = run.pole.seen;
        }
        last = LineRun{};
        last.line_no = line_no;
        last.pole = pole;
        stages_.run(current, last, held_);
    } catch (const InputError&) {
        return false;
    }
    return true;
}

void LookBack::release(std::size_t bytes, std::size_t moves, std::string& out) {
    if (bytes > 0) {  // none on most lines (nothing held: see feed)
        out.append(held_, 0, bytes);
        held_.erase(0, bytes);
    }
    if (log_) log_->release(moves);
}

}  // namespace xlate5
