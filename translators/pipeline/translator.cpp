// SPDX-License-Identifier: GPL-3.0-or-later
// The front door: wires the forward stages (or the inverse pipeline) together.
// What it may call: see translator.hpp.
#include "translators/pipeline/translator.hpp"

#include <algorithm>
#include <cmath>
#include <variant>

#include "translators/error.hpp"
#include "translators/inspect/inverse.hpp"
#include "translators/pipeline/travel_clamp.hpp"
#include "translators/pipeline/keep_out.hpp"
#include "translators/pipeline/lookback.hpp"
#include "translators/pipeline/planner.hpp"
#include "translators/pipeline/resolve.hpp"

namespace xlate5 {

// The forward pipeline's stages and the one state they share: a line goes interpreter ->
// commands -> (resolve -> [keep-out] -> planner | emitter) -> text.
struct Translator::Forward final : LineStages {
    Forward(const Kinematics& kin, const TranslatorOptions& o)
        : state(start(kin, o)),
          saved(state.line),
          log(o.report ? std::make_optional<MoveLog>(*o.report, kin.machine()) : std::nullopt),
          planner(kin, state.line.planner, state.emitter, log ? &*log : nullptr),
          resolver(kin.machine(), planner, state.line.planner),
          interpreter(kin.machine(), state.line.modal, o.input_name, o.extruder_letter),
          lookback(*this, state, log ? &*log : nullptr),
          input_name(o.input_name) {
        const FirmwareDialect firmware = kin.machine().dialect.firmware;
        long_lines_matter = firmware == FirmwareDialect::Marlin || firmware == FirmwareDialect::MarlinArticulated;
        if (o.keep_out) keep_out.emplace(kin, *o.keep_out, state.line.planner, planner);
        // The collision check watches every piece the emitter writes (collide.hpp).
        if (kin.machine().geometry && o.collision != CollisionPolicy::Off) {
            collide = std::make_unique<CollisionStage>(kin, o.collision, state.line.collide, state.line.modal.modes, o.reroute, o.lift);
            // Told with the emitter's count, so the preview marks the written move it belongs to.
            if (o.on_collision)
                collide->on_collision = [emitter = &state.emitter, told = o.on_collision](const CollisionEvent& ev) {
                    CollisionEvent placed = ev;
                    placed.moves_written = emitter->moves_written();
                    told(placed);
                };
            state.emitter.set_observer(collide.get());
        }
    }

    static ForwardState start(const Kinematics& kin, const TranslatorOptions& o) {
        ForwardState s(kin.machine());
        s.line.planner.q = kin.machine().home_joints();
        s.line.planner.pose = kin.forward(s.line.planner.q);
        s.line.modal.mode = o.start_mode.value_or(kin.machine().start_mode);
        return s;
    }

    void feed_line(std::string_view line, LineRun& run, std::string& out, const LineState* before) override;
    void run_command(const cmd::Command& c, LineRun& run, std::string& out);
    void tool_move(const cmd::ToolMove& mv, LineRun& run, std::string& out);
    void arc(const cmd::Arc& a, LineRun& run, std::string& out);
    void fit_lines(std::string& out, std::size_t start, std::string_view line, std::uint64_t line_no);

    ForwardState state;
    LineState saved;  // the state before the current line (when the look-back keeps none)
    std::optional<MoveLog> log;
    Planner planner;
    Resolver resolver;
    std::optional<KeepOutStage> keep_out;
    Interpreter interpreter;
    LookBack lookback;
    std::unique_ptr<CollisionStage> collide;
    cmd::CommandList commands;  // the current line's
    std::string input_name;
    std::function<void(const std::string&)> notice;  // a display text shortened (TranslatorOptions::notice)
    std::uint64_t noticed_line = 0;  // the look-back replays lines: each is told once
    bool long_lines_matter = false;  // the firmware is Marlin's
};

void Translator::Forward::feed_line(std::string_view line, LineRun& run, std::string& out, const LineState* before) {
    state.line.collide.line = run.line_no;  // the beads this line lays are its own (collide.hpp)
    // Nothing is kept of a line that fails: output, joints, pose, modes (from `before`, or a copy
    // taken here).
    const std::size_t out_start = out.size();
    if (!before) {
        saved = state.line;
        before = &saved;
    }
    try {
        interpreter.interpret(line, run.line_no, commands);
        for (const cmd::Command& c : commands.commands) run_command(c, run, out);
        // Only output of more than 95 characters can hold a line that long (a cheap test per line).
        if (out.size() - out_start > kMarlinLineChars && long_lines_matter) fit_lines(out, out_start, line, run.line_no);
    } catch (const InputError&) {
        throw;  // a line the interpreter cannot read: nothing has changed
    } catch (...) {
        // What the firmware was told of a failed line is not known either.
        out.resize(out_start);
        state.line = *before;
        planner.position_unknown();
        try {
            throw;
        } catch (const LineError& e) {
            throw InputError(input_name, run.line_no, e.column(), e.what());
        }
    }
}

void Translator::Forward::run_command(const cmd::Command& c, LineRun& run, std::string& out) {
    if (const auto* mv = std::get_if<cmd::ToolMove>(&c)) return tool_move(*mv, run, out);
    if (const auto* p = std::get_if<cmd::Passthrough>(&c)) {
        using Effect = cmd::Passthrough::Effect;
        if (p->effect == Effect::PositionUnknown) planner.position_unknown();  // the firmware moves where xlate5 cannot follow
        if (p->effect == Effect::FeedPerMinute || p->effect == Effect::InverseTime) state.emitter.feed_mode_sent(p->effect == Effect::InverseTime);
        return state.emitter.pass(out, commands.text_of(*p));
    }
    if (const auto* a = std::get_if<cmd::Arc>(&c)) return arc(*a, run, out);
    if (const auto* mv = std::get_if<cmd::JointMove>(&c)) return planner.joint_move(*mv, out);
    if (const auto* set = std::get_if<cmd::SetPosition>(&c)) return planner.set_position(*set, out);
    if (const auto* home = std::get_if<cmd::Home>(&c)) return planner.home(*home);
    if (const auto* to = std::get_if<cmd::MovedTo>(&c)) return planner.moved_to(*to);
    if (std::holds_alternative<cmd::NewMode>(c)) return planner.new_mode();
}

// Tool moves go through the keep-out stage (which sets R) before the planner, when set.
void Translator::Forward::tool_move(const cmd::ToolMove& c, LineRun& run, std::string& out) {
    const ToolMove& mv = resolver.tool_move(c);
    if (keep_out) keep_out->tool_move(mv, run, out);
    else planner.tool_move(mv, run, out);
    planner.extruded(c.e, c.e_relative);
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

void Translator::Forward::fit_lines(std::string& out, std::size_t start, std::string_view line, std::uint64_t line_no) {
    fit_marlin_lines(out, start, line, interpreter.text_argument(), [&](std::string_view command) {
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
        clamp_ = std::make_unique<TravelClamp>(kinematics, options.input_name, options.notice);
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
    auto& s = forward_->state.line;
    bool same = q.size() == s.planner.q.size();
    for (std::size_t j = 0; same && j < q.size(); ++j) same = std::abs(q[j] - s.planner.q[j]) <= within;
    if (!same) forward_->planner.moved_to(q);
    if (e) s.planner.e = *e;
}

const std::vector<double>& Translator::joints() const { return forward_ ? forward_->state.line.planner.q : inverse_->joints(); }
const Pose& Translator::pose() const { return forward_ ? forward_->state.line.planner.pose : inverse_->pose(); }
const Eigen::Vector3d& Translator::program_offset() const {
    static const Eigen::Vector3d kNone = Eigen::Vector3d::Zero();  // joint space has no program frame
    return forward_ ? forward_->state.line.planner.offset : kNone;
}
CollisionStage* Translator::collision() { return forward_ ? forward_->collide.get() : nullptr; }
OrientationMode Translator::mode() const { return forward_ ? forward_->state.line.modal.mode : OrientationMode::Joints; }
const Modes& Translator::modes() const { return forward_ ? forward_->state.line.modal.modes : inverse_->modes(); }

}  // namespace xlate5
