// SPDX-License-Identifier: GPL-3.0-or-later
// The look-back over the interpreter and planner: held output, checkpoint, replay.
// What it may call: see lookback.hpp.
#include "translators/pipeline/lookback.hpp"

#include "translators/error.hpp"

namespace xlate5 {

LookBack::LookBack(LineStages& stages, ForwardState& state, MoveLog* log)
    : stages_(stages), state_(state), log_(log), before_line_(state), checkpoint_(state) {
    // Moves are held, with look-back or not, at least for their line: a refused line's are dropped with its output.
    if (log_) log_->hold(true);
}

namespace {
// A linear joint past its travel is a placement, not a turn: no travel move fixes it.
std::string linear_limit_advice() {
    return "; the part lies outside the machine's travel there: the slicer's origin (a corner or the middle of its bed) is "
           "not where the machine's is, or the part is too large. Place the part in the slicer so that its moves stay within "
           "the machine file's limits (xlate5 --machine NAME pose shows where the tip is for given joints), or set the limits "
           "to the machine's real travel";
}
}  // namespace

void LookBack::set_lines(std::size_t lines, int candidates) {
    lines_ = lines;
    candidates_ = candidates < 1 ? 1 : candidates > kMaxCandidates ? kMaxCandidates : candidates;
}

// Without look-back: the line's output goes out at once; only a travel move that itself runs
// into a limit unwinds (the planner tries its other ends).
void LookBack::feed_alone(std::string_view line, std::uint64_t line_no, std::string& out) {
    LineRun run;
    run.line_no = line_no;
    const std::size_t moves_start = held_moves();
    try {
        stages_.feed_line(line, run, out);
    } catch (const InputError& e) {
        if (log_) log_->drop_held_from(moves_start);
        if (!run.hit_limit) throw;
        throw InputError(e.file(), e.line(), e.column(),
                         e.message() + (run.linear_limit ? linear_limit_advice()
                                                         : "; turn the joint back on a travel move before this line, or plan the path "
                                                           "within the limits"));
    }
    if (log_) log_->release(held_moves());
}

// What a line refused on a joint limit is told to do, after the limit's own message.
std::string LookBack::refusal_advice(bool linear, bool had_checkpoint) const {
    if (linear) return linear_limit_advice();
    if (had_checkpoint)
        return "; turning it back on the travel move at line " + std::to_string(checkpoint_line_) +
               " does not keep the printing from there to here within the limits: add a travel move (G0, or G1 "
               "without E) nearer this line, where the joint can turn back, or plan the path within the limits";
    return "; there is no travel move (G0, or G1 without E) within the " + std::to_string(lines_) +
           " lines before this one to turn the joint back on: add one before this line, or plan the path "
           "within the limits";
}

void LookBack::feed(std::string_view line, std::uint64_t line_no, std::string& out) {
    if (lines_ == 0) return feed_alone(line, line_no, out);
    LineRun run;
    run.line_no = line_no;
    before_line_ = state_;
    // With no window open nothing is held (held_ is empty): the line's output goes straight to
    // `out`, where only a travel move's has to be taken back into held_ (below). One copy of the
    // output fewer on most lines.
    const bool direct = !have_checkpoint_;
    std::string& to = direct ? out : held_;
    const std::size_t held_start = to.size(), moves_start = held_moves();
    run.pole.seen = have_checkpoint_ ? choices_ : 0;
    const int seen_before = run.pole.seen;
    try {
        stages_.feed_line(line, run, to, &before_line_.line);  // one copy of the state per line, not two
    } catch (const InputError& e) {
        if (!run.hit_limit) {
            // A refused line (the service goes on after one typed in a terminal) leaves nothing
            // behind: its output was only held, so what the emitter remembers of the firmware is
            // restored too, the report forgets its moves (an arc's chords before the one refused),
            // and later lines print as if it never came.
            state_ = before_line_;
            to.resize(held_start);
            if (log_) log_->drop_held_from(moves_start);
            throw;
        }
        const bool had_checkpoint = have_checkpoint_;
        const bool linear = run.linear_limit;
        // Without a window there is nothing to unwind (unwind_before refuses at once), so `to` is
        // still the one written to.
        if (!unwind_before(line, line_no, run)) {
            state_ = before_line_;  // as for any refused line (above)
            to.resize(held_start);
            if (log_) log_->drop_held_from(moves_start);
            throw InputError(e.file(), e.line(), e.column(), e.message() + refusal_advice(linear, had_checkpoint));
        }
    }
    if (direct && run.travels) {
        // The travel move's own output starts the window: held, not yet final.
        held_.assign(out, held_start, std::string::npos);
        out.resize(held_start);
    }
    if (run.travels) {
        // A travel move: the next checkpoint. What came before it is final.
        release(direct ? 0 : held_start, moves_start, out);
        checkpoint_ = before_line_;
        have_checkpoint_ = true;
        checkpoint_line_ = line_no;
        chosen_ = -1;
        flips_ = PoleChoices{};
        choices_ = run.pole.seen - seen_before;  // the travel line's own choices start the window's count
        window_text_.clear();
        window_lines_.clear();
    } else if (have_checkpoint_) {
        choices_ = run.pole.seen;
    }
    if (!have_checkpoint_ && held_.empty()) {
        // No window open (most lines): nothing is held, and the window's lists are empty since it
        // last closed; only the report's moves of this line are final.
        if (log_) log_->release(held_moves());
        return;
    }
    if (have_checkpoint_) {
        window_text_.append(line);
        window_text_ += '\n';
        window_lines_.push_back(line_no);
    }
    // Memory stays bounded: past the window (in lines or in bytes) the held lines are final.
    if (!have_checkpoint_ || window_lines_.size() > lines_ || window_text_.size() > kMaxWindowBytes ||
        held_.size() > kMaxHeldBytes) {
        release(held_.size(), held_moves(), out);
        have_checkpoint_ = false;
        window_text_.clear();
        window_lines_.clear();
    }
}

void LookBack::finish(std::string& out) {
    release(held_.size(), held_moves(), out);
    have_checkpoint_ = false;
    window_text_.clear();
    window_lines_.clear();
}

// The line at line_no runs a joint past its limit: translate the window again from the
// checkpoint, its travel move ending on each other solution of its pose in turn (nearest
// first), until the window and this line fit. On failure everything is as before.
bool LookBack::unwind_before(std::string_view line, std::uint64_t line_no, LineRun& last) {
    if (!have_checkpoint_ || window_lines_.empty()) return false;
    const std::string held_saved = held_;
    const MoveLog::Held log_saved = log_ ? log_->held() : MoveLog::Held{};
    const int was = chosen_;
    // The travel move's ends in turn, the one it took first (its choices so far kept), then the
    // others. With each, as it is, then with one more branch choice near a pole taken the other
    // way: which branch a printed loop needs where it passes a bounded turning joint's pole can
    // depend on where it goes long after. At most kMaxReplays translations of the window.
    // Then all of that again with a flipped choice allowed a half turn in place where its move
    // passes nearest the pole (PoleChoices::turns): the last resort, each pass within kMaxReplays.
    const int first_choices = last.pole.seen;
    for (const bool turns : {false, true}) {
        int replays = 0;
        bool missing = false;
        last.pole.seen = first_choices;
        for (int k = -1; k < candidates_ && !missing && replays < kMaxReplays; ++k) {
            const bool taken = k < 0;  // first the end taken (-1 its usual one), then the others
            if (!taken && k == was) continue;
            const int candidate = taken ? was : k;
            PoleChoices base = taken ? flips_ : PoleChoices{};
            base.turns = turns;
            // The end as it is (tried already, for the end taken, by the line's own translation).
            int choices = last.pole.seen;  // the choices up to where the line failed
            // (With turns, the end taken with its flips is another translation than the line's own.)
            if (!taken || (turns && base.n_flips > 0)) {
                ++replays;
                if (replay(candidate, base, line, line_no, last, missing)) {
                    chosen_ = candidate;
                    flips_ = base;
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
                if (replay(candidate, flips, line, line_no, last, none)) {
                    chosen_ = candidate;
                    flips_ = flips;
                    return true;
                }
            }
        }
    }
    state_ = before_line_;
    held_ = held_saved;
    if (log_) log_->set_held(log_saved);
    return false;
}

// The window translated again from the checkpoint, its travel move ending on solution
// `candidate` (-1: its usual end) and the branch choices in `flips` taken the other way, then the
// line: true when all of it fits. `missing`: there is no solution `candidate`.
bool LookBack::replay(int candidate, const PoleChoices& flips, std::string_view line, std::uint64_t line_no, LineRun& last,
                      bool& missing) {
    state_ = checkpoint_;
    held_.clear();
    if (log_) log_->drop_held();
    PoleChoices pole = flips;
    pole.seen = 0;
    try {
        std::size_t at = 0;
        bool first = true;
        for (const std::uint64_t no : window_lines_) {
            const std::size_t nl = window_text_.find('\n', at);
            LineRun run;
            run.line_no = no;
            run.pole = pole;
            if (first) run.end_candidate = candidate;  // the checkpoint's travel move ends on this solution
            first = false;
            try {
                stages_.feed_line(std::string_view(window_text_).substr(at, nl - at), run, held_);
            } catch (const InputError&) {
                missing = run.candidate_missing;
                throw;
            }
            pole.seen = run.pole.seen;
            at = nl + 1;
        }
        last = LineRun{};
        last.line_no = line_no;
        last.pole = pole;
        stages_.feed_line(line, last, held_);
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
