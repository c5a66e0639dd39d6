// SPDX-License-Identifier: GPL-3.0-or-later
// The front door: wires the forward stages (or the inverse pipeline) together.
// What it may call: see translator.hpp.
#include "translators/pipeline/translator.hpp"

#include <algorithm>
#include <cmath>
#include <span>
#include <variant>

#include "translators/error.hpp"
#include "translators/inspect/inverse.hpp"
#include "translators/pipeline/travel_clamp.hpp"
#include "translators/pipeline/keep_out.hpp"
#include "translators/pipeline/lookback.hpp"
#include "translators/pipeline/motion.hpp"
#include "translators/pipeline/planner.hpp"
#include "translators/pipeline/resolve.hpp"

namespace xlate5 {

namespace {

ForwardState start_state(const Kinematics& kin, const TranslatorOptions& o) {
    ForwardState s(kin.machine());
    s.stages.planner.q = kin.machine().home_joints();
    s.stages.planner.pose = kin.forward(s.stages.planner.q);
    s.modal.mode = o.start_mode.value_or(kin.machine().start_mode);
    return s;
}

}  // namespace

// The planner's joint-space output (its joint moves, G92s and re-zeros: nominal joints, the
// machine's first n) to the firmware: through a compensation stage of its own (the motion stage
// has another) to the emitter.
struct JointWriter {
    CompensationStage compensation;
    JointEmitter& emitter;
    std::size_t n;
    void write(const JointStep& step, std::string& out) {
        const std::span<const double> q(step.q.data(), n);
        const auto sent = compensation.apply(q);
        if (!sent.ok()) throw LineError(1, sent.why());
        emitter.move(out, step.gcode, q, sent.sent, step.given, step.e, step.f, step.inverse_time);
    }
    void write(const SetJoints& set, std::string& out) {
        const std::span<const double> q(set.q.data(), n);
        const auto sent = compensation.apply(q);
        if (!sent.ok()) throw LineError(1, sent.why());
        emitter.set_position(out, q, sent.sent, set.which, set.e);
    }
};

namespace {

// G49 and G92: planner -> JointStep / SetJoints -> compensation -> emitter. Out of line: rare,
// and the dispatch of every command (run_command) stays as light as the tool moves need.
[[gnu::noinline]] void joint_move(Planner& planner, JointWriter& writer, const cmd::JointMove& mv, std::string& out) {
    writer.write(planner.joint_move(mv), out);
    planner.extruded(mv.e, mv.e_relative);
}

[[gnu::noinline]] void set_position(Planner& planner, JointWriter& writer, const cmd::SetPosition& set, std::string& out) {
    writer.write(planner.set_position(set), out);
}

}  // namespace

// The forward pipeline's stages and the one state they share: a line goes interpreter ->
// commands -> (resolve -> [keep-out] -> planner -> motion -> planner | planner -> compensation ->
// emitter | emitter) -> text. The resolver, the keep-out stage, the planner and the motion stage
// hold none of each other: each hands its value back here, and this passes it on. Only the
// emitter writes text: the motion stage through its own compensation stage and the emitter, the
// planner's joint moves and G92s through this one's.
struct Translator::Forward final : LineStages {
    Forward(const Kinematics& kin, const TranslatorOptions& o)
        : state(start_state(kin, o)),
          log(o.report ? std::make_optional<MoveLog>(*o.report, kin.machine()) : std::nullopt),
          planner(kin, state.stages.planner, log ? &*log : nullptr),
          motion(kin, state.stages.emitter),
          joints_out{CompensationStage(kin.machine().compensation), state.stages.emitter, kin.machine().joints.size()},
          resolver(kin, state.stages.planner),
          interpreter(kin.machine(), state.modal, o.input_name, o.extruder_letter),
          lookback(*this, state, log ? &*log : nullptr),
          input_name(o.input_name) {
        const FirmwareDialect firmware = kin.machine().dialect.firmware;
        long_lines_matter = firmware == FirmwareDialect::Marlin || firmware == FirmwareDialect::MarlinArticulated;
        if (o.keep_out) keep_out.emplace(kin, *o.keep_out, state.stages.planner);
        // The collision check watches every piece the emitter writes (collide.hpp).
        if (kin.machine().geometry && o.collision != CollisionPolicy::Off) {
            collide = std::make_unique<CollisionStage>(kin, o.collision, state.stages.collide, line_modes, o.reroute, o.lift);
            // Told with the emitter's count, so the preview marks the written move it belongs to;
            // not told again while the look-back replays lines told already.
            if (o.on_collision)
                collide->on_collision = [emitter = &state.stages.emitter, quiet = &quiet, told = o.on_collision](const CollisionEvent& ev) {
                    if (*quiet) return;
                    CollisionEvent placed = ev;
                    placed.moves_written = emitter->moves_written();
                    told(placed);
                };
            state.stages.emitter.set_observer(collide.get());
        }
        lookback.restart();  // its copy of the stages' state, with the observer set
    }

    bool interpret(std::string_view line, const LineRun& run, HeldLine& held) override;
    bool may_travel(const HeldLine& held) const;
    void run(const HeldLine& held, LineRun& run, std::string& out) override;
    // The firmware's position is no longer exactly known (a code that moves it, homing, a failed
    // line): the emitter believes it is where the planner has the joints.
    void position_unknown() override { state.stages.emitter.invalidate(state.stages.planner.q); }
    void set_quiet(bool on) override { quiet = on; }
    void run_command(const cmd::Command& c, const cmd::CommandList& list, LineRun& run, std::string& out);
    void tool_move(const cmd::ToolMove& mv, LineRun& run, std::string& out);
    void move(const ToolMove& mv, LineRun& run, std::string& out);
    void arrived(const MovePlan& plan, MoveResult* figures, LineRun& run, std::string& out);
    void keep_out_moves(const ToolMove& mv, LineRun& run, std::string& out);
    void arc(const cmd::Arc& a, LineRun& run, std::string& out);
    void fit_lines(std::string& out, std::size_t start, const HeldLine& held, std::uint64_t line_no);

    ForwardState state;
    std::optional<MoveLog> log;
    Planner planner;
    MotionStage motion;
    JointWriter joints_out;  // the planner's joint moves and G92s
    MoveResult measured;  // the report's figures of the move being made (reused move after move)
    Resolver resolver;
    std::optional<KeepOutStage> keep_out;
    Interpreter interpreter;
    LookBack lookback;
    std::unique_ptr<CollisionStage> collide;
    // The modes the collision stage reads E under: the line's being run (HeldLine::e_relative),
    // which a replay runs after later lines were read.
    Modes line_modes;
    bool quiet = false;  // a replay of lines whose collisions were told (LineStages::set_quiet)
    std::string input_name;
    std::function<void(const std::string&)> notice;  // a display text shortened (TranslatorOptions::notice)
    std::uint64_t noticed_line = 0;  // the look-back replays lines: each is told once
    bool long_lines_matter = false;  // the firmware is Marlin's
};

bool Translator::Forward::interpret(std::string_view line, const LineRun& run, HeldLine& held) {
    // The commands' passed numbers are views into the text they were read from: the held copy
    // (which the lexer reads in place, a NUL after it).
    held.text.assign(line);
    held.line_no = run.line_no;
    try {
        interpreter.interpret(held.text, run.line_no, held.commands, true);
    } catch (const LineError& e) {
        throw InputError(input_name, run.line_no, e.column(), e.what());
    }
    held.text_argument = interpreter.text_argument();
    held.e_relative = state.modal.modes.e_relative;
    return may_travel(held);
}

// A travel move is a tool move that does not extrude (Planner::plan): with E followed
// through the line as the planner follows it, a line whose one tool move prints does not travel.
// The keep-out stage and an arc cut a move into pieces that may not extrude.
inline bool Translator::Forward::may_travel(const HeldLine& held) const {
    if (keep_out) return true;
    const std::vector<cmd::Command>& commands = held.commands.commands;
    double e = state.stages.planner.e;
    if (commands.size() == 1) {  // most lines: one move
        if (const auto* mv = std::get_if<cmd::ToolMove>(&commands[0])) return !extrudes(mv->e, mv->e_relative, e);
    }
    bool travels = false;
    for (const cmd::Command& c : commands) {
        if (const auto* mv = std::get_if<cmd::ToolMove>(&c)) {
            travels = travels || !extrudes(mv->e, mv->e_relative, e);
            if (mv->e) e = mv->e_relative ? e + mv->e->value : mv->e->value;
        } else if (const auto* jm = std::get_if<cmd::JointMove>(&c)) {
            if (jm->e) e = jm->e_relative ? e + jm->e->value : jm->e->value;
        } else if (const auto* set = std::get_if<cmd::SetPosition>(&c)) {
            if (set->e) e = set->e->value;
        } else if (std::holds_alternative<cmd::Arc>(c)) {
            return true;
        }
    }
    return travels;
}

void Translator::Forward::run(const HeldLine& held, LineRun& run, std::string& out) {
    state.stages.collide.line = run.line_no;  // the beads this line lays are its own (collide.hpp)
    line_modes.e_relative = held.e_relative;
    const std::size_t out_start = out.size();
    try {
        for (const cmd::Command& c : held.commands.commands) run_command(c, held.commands, run, out);
        // Only output of more than 95 characters can hold a line that long (a cheap test per line).
        if (out.size() - out_start > kMarlinLineChars && long_lines_matter) fit_lines(out, out_start, held, run.line_no);
    } catch (...) {
        // Nothing is kept of a line that fails: its output (the look-back restores the state).
        out.resize(out_start);
        try {
            throw;
        } catch (const LineError& e) {
            throw InputError(input_name, run.line_no, e.column(), e.what());
        }
    }
}

void Translator::Forward::run_command(const cmd::Command& c, const cmd::CommandList& list, LineRun& run, std::string& out) {
    if (const auto* mv = std::get_if<cmd::ToolMove>(&c)) return tool_move(*mv, run, out);
    if (const auto* p = std::get_if<cmd::Passthrough>(&c)) {
        using Effect = cmd::Passthrough::Effect;
        if (p->effect == Effect::PositionUnknown) position_unknown();  // the firmware moves where xlate5 cannot follow
        if (p->effect == Effect::FeedPerMinute || p->effect == Effect::InverseTime) state.stages.emitter.feed_mode_sent(p->effect == Effect::InverseTime);
        return state.stages.emitter.pass(out, list.text_of(*p));
    }
    if (const auto* a = std::get_if<cmd::Arc>(&c)) return arc(*a, run, out);
    if (const auto* mv = std::get_if<cmd::JointMove>(&c)) return joint_move(planner, joints_out, *mv, out);
    if (const auto* set = std::get_if<cmd::SetPosition>(&c)) return set_position(planner, joints_out, *set, out);
    if (const auto* home = std::get_if<cmd::Home>(&c)) {
        planner.home(*home);
        return position_unknown();
    }
    if (const auto* to = std::get_if<cmd::MovedTo>(&c)) {
        planner.moved_to(*to);
        return position_unknown();
    }
    if (std::holds_alternative<cmd::NewMode>(c)) return planner.new_mode();
}

// One tool move: planner -> PlannedMove -> motion (pieces -> compensation -> emitter) ->
// MotionOutcome -> planner [-> re-zero G92s -> compensation -> emitter]. The outcome goes back
// to the planner because the next move starts where this one ended, which only the motion stage
// knows (the split's last part may arrive elsewhere than the planned end); the planner may also
// have a refused move written again. Always inline: every tool move's path (out of line it costs
// rw2 unsplit about 60 instructions a line).
[[gnu::always_inline]] inline void Translator::Forward::move(const ToolMove& mv, LineRun& run, std::string& out) {
    MovePlan& plan = planner.plan(mv, run);
    MoveResult* figures = plan.measure ? &measured : nullptr;
    auto arrive = [&](const MotionOutcome& outcome) {
        if (planner.arrive(plan, outcome, figures != nullptr, run)) arrived(plan, figures, run, out);
    };
    const MotionOutcome outcome = motion.emit(plan.move, out, figures);
    if (Planner::retry_in_angle_form(plan, outcome)) return arrive(motion.emit(plan.move, out, figures));
    arrive(outcome);
}

// A move the planner has more to settle: the report's figures, and the G92s that re-zero a
// wound-up rotary (Planner::rezero), written after the move.
[[gnu::noinline]] void Translator::Forward::arrived(const MovePlan& plan, MoveResult* figures, LineRun& run, std::string& out) {
    JointEmitter& emitter = state.stages.emitter;
    if (figures) figures->moves_written = emitter.moves_written();  // the report joins the move to its output line
    const std::span<const SetJoints> g92s = planner.arrived(plan, figures, run);
    for (const SetJoints& g92 : g92s) joints_out.write(g92, out);
    if (!g92s.empty() && log && !figures) log->add_rezeros(run.line_no, emitter.moves_written(), int(g92s.size()));
}

// Tool moves go through the keep-out stage (which sets R) before the planner, when set.
void Translator::Forward::tool_move(const cmd::ToolMove& c, LineRun& run, std::string& out) {
    const ToolMove& mv = resolver.tool_move(c);
    if (keep_out) keep_out_moves(mv, run, out);
    else move(mv, run, out);
    planner.extruded(c.e, c.e_relative);
}

// The keep-out stage's moves run in turn, then its refusal, if any, where it found it.
void Translator::Forward::keep_out_moves(const ToolMove& mv, LineRun& run, std::string& out) {
    const KeepOutMoves& moves = keep_out->tool_move(mv);
    for (const KeepOutMoves::Step& step : moves.steps) {
        if (!step.turn) {
            move(step.move, run, out);
            continue;
        }
        LineRun turn_run;  // a turn in place is no travel move: it never unwinds
        turn_run.line_no = run.line_no;
        try {
            move(step.move, turn_run, out);
        } catch (...) {
            run.hit_limit = run.hit_limit || turn_run.hit_limit;
            throw;
        }
    }
    if (moves.refusal) {
        run.hit_limit = run.hit_limit || moves.refused_at_limit;
        throw *moves.refusal;
    }
}

// Each chord may be split further: the line's output as a whole is bounded too.
void Translator::Forward::arc(const cmd::Arc& a, LineRun& run, std::string& out) {
    const int chords = resolver.start_arc(a);
    std::size_t counted = out.size();
    long pieces = 0;
    for (int k = 1; k <= chords; ++k) {
        tool_move(resolver.chord(k), run, out);
        pieces += std::count(out.begin() + std::ptrdiff_t(counted), out.end(), '\n');
        counted = out.size();
        resolver.check_arc_lines(pieces);
    }
}

void Translator::Forward::fit_lines(std::string& out, std::size_t start, const HeldLine& held, std::uint64_t line_no) {
    fit_marlin_lines(out, start, held.text, held.text_argument, [&](std::string_view command) {
        if (!notice || line_no <= noticed_line) return;
        noticed_line = line_no;
        notice(input_name + ":" + std::to_string(line_no) + ": note: " + std::string(command) + "'s text shortened to " +
               std::to_string(kMarlinLineChars) + " characters (Marlin reads at most " + std::to_string(kMarlinLineChars) +
               " a line and would run the rest as a command)");
    });
}

Translator::Translator(const Kinematics& kinematics, TranslatorOptions options) {
    if (options.from) {
        // The source machine's joints -> tool space (I J K: no rotary letters of either machine)
        // -> this machine. The forward side reads what the inverse writes: G43.5, E as E.
        retarget_ = true;
        input_name_ = options.input_name;
        inverse_ = std::make_unique<InverseTranslator>(*options.from, options.input_name, options.extruder_letter, OrientationMode::Vector);
        clamp_ = std::make_unique<TravelClamp>(kinematics, options.input_name, options.notice,
                                               Eigen::Vector3d(options.place[0], options.place[1], options.place[2]));
        inverse_->set_retarget(*clamp_);
        if (options.compact_words) inverse_->set_compact_words();
        options.start_mode = OrientationMode::Vector;
        options.extruder_letter = 'E';
        options.compact_words = false;
        forward_ = std::make_unique<Forward>(kinematics, options);
        return;
    }
    if (options.inverse) {
        inverse_ = std::make_unique<InverseTranslator>(kinematics, options.input_name, options.extruder_letter, options.preview_form);
        if (options.compact_words) inverse_->set_compact_words();
        return;
    }
    forward_ = std::make_unique<Forward>(kinematics, options);
    if (options.compact_words) forward_->interpreter.set_compact_words();
    if (options.notice) forward_->notice = options.notice;
}

Translator::~Translator() = default;

void Translator::feed(std::string_view line, std::uint64_t line_no, std::string& out) {
    if (retarget_) {
        between_.clear();
        inverse_->feed(line, line_no, between_);
        // Each tool-space line the source's line became, on this machine. An error there names
        // the input line; its column would be the tool-space line's, so it says so instead.
        std::string_view rest = between_;
        while (!rest.empty()) {
            const std::size_t end = rest.find('\n');
            const std::string_view one = rest.substr(0, end);
            try {
                forward_->lookback.feed(one, line_no, out);
            } catch (const InputError& e) {
                throw InputError(input_name_, line_no, 1, e.message() + " (at tool-space pose '" + std::string(one) + "')");
            }
            if (end == std::string_view::npos) break;
            rest.remove_prefix(end + 1);
        }
        return;
    }
    if (inverse_) inverse_->feed(line, line_no, out);
    else forward_->lookback.feed(line, line_no, out);
}

void Translator::set_lookback(std::size_t lines, int candidates) {
    if (forward_) forward_->lookback.set_lines(lines, candidates);
}

bool Translator::holding() const { return forward_ && forward_->lookback.holding(); }

void Translator::finish(std::string& out) {
    if (forward_) forward_->lookback.finish(out);
}

void Translator::place_at(const std::vector<double>& q, std::optional<double> e, double within) {
    if (!forward_ || holding()) return;
    auto& s = forward_->state.stages;
    bool same = q.size() == s.planner.q.size();
    for (std::size_t j = 0; same && j < q.size(); ++j) same = std::abs(q[j] - s.planner.q[j]) <= within;
    if (!same) {
        forward_->planner.moved_to(q);
        forward_->position_unknown();
    }
    if (e) s.planner.e = *e;
    forward_->lookback.restart();  // a replay starts from the state as placed
}

const std::vector<double>& Translator::joints() const { return forward_ ? forward_->state.stages.planner.q : inverse_->joints(); }
const Pose& Translator::pose() const { return forward_ ? forward_->state.stages.planner.pose : inverse_->pose(); }
const Eigen::Vector3d& Translator::program_offset() const {
    static const Eigen::Vector3d kNone = Eigen::Vector3d::Zero();  // joint space has no program frame
    return forward_ ? forward_->state.stages.planner.offset : kNone;
}
CollisionStage* Translator::collision() { return forward_ ? forward_->collide.get() : nullptr; }
OrientationMode Translator::mode() const { return forward_ ? forward_->state.modal.mode : OrientationMode::Joints; }
const Modes& Translator::modes() const { return forward_ ? forward_->state.modal.modes : inverse_->modes(); }

}  // namespace xlate5
