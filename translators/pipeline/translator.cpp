// SPDX-License-Identifier: GPL-3.0-or-later
// The front door: wires the forward stages (or the inverse pipeline) together.
// What it may call: see translator.hpp.
#include "translators/pipeline/translator.hpp"

#include <cmath>

#include "translators/error.hpp"
#include "translators/inspect/inverse.hpp"
#include "translators/pipeline/travel_clamp.hpp"
#include "translators/pipeline/keep_out.hpp"
#include "translators/pipeline/lookback.hpp"
#include "translators/pipeline/planner.hpp"

namespace xlate5 {

// The forward pipeline's stages and the one state they share.
struct Translator::Forward {
    Forward(const Kinematics& kin, const TranslatorOptions& o)
        : state(start(kin, o)),
          log(o.report ? std::make_optional<MoveLog>(*o.report, kin.machine()) : std::nullopt),
          planner(kin, state.line.planner, state.emitter, log ? &*log : nullptr),
          interpreter(kin, state.line, planner, o.input_name, o.extruder_letter),
          lookback(interpreter, state, log ? &*log : nullptr) {
        if (o.keep_out) {
            keep_out.emplace(kin, *o.keep_out, state.line.planner, planner);
            interpreter.set_keep_out(&*keep_out);
        }
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

    ForwardState state;
    std::optional<MoveLog> log;
    Planner planner;
    std::optional<KeepOutStage> keep_out;
    Interpreter interpreter;
    LookBack lookback;
    std::unique_ptr<CollisionStage> collide;
};

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
    if (options.notice) forward_->interpreter.set_notice(options.notice);
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
    if (e) s.modal.modes.e_position = *e;
}

const std::vector<double>& Translator::joints() const { return forward_ ? forward_->state.line.planner.q : inverse_->joints(); }
const Pose& Translator::pose() const { return forward_ ? forward_->state.line.planner.pose : inverse_->pose(); }
const Eigen::Vector3d& Translator::program_offset() const {
    static const Eigen::Vector3d kNone = Eigen::Vector3d::Zero();  // joint space has no program frame
    return forward_ ? forward_->state.line.modal.offset : kNone;
}
CollisionStage* Translator::collision() { return forward_ ? forward_->collide.get() : nullptr; }
OrientationMode Translator::mode() const { return forward_ ? forward_->state.line.modal.mode : OrientationMode::Joints; }
const Modes& Translator::modes() const { return forward_ ? forward_->state.line.modal.modes : inverse_->modes(); }

}  // namespace xlate5
