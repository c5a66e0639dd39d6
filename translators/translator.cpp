// The front door: wires the forward stages (or the inverse pipeline) together.
// What it may call: see translator.hpp.
#include "translators/translator.hpp"

#include "translators/inverse.hpp"
#include "translators/keep_out.hpp"
#include "translators/lookback.hpp"
#include "translators/planner.hpp"

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
};

Translator::Translator(const Kinematics& kinematics, TranslatorOptions options) {
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

const std::vector<double>& Translator::joints() const { return inverse_ ? inverse_->joints() : forward_->state.line.planner.q; }
const Pose& Translator::pose() const { return inverse_ ? inverse_->pose() : forward_->state.line.planner.pose; }
const Eigen::Vector3d& Translator::program_offset() const {
    static const Eigen::Vector3d kNone = Eigen::Vector3d::Zero();  // joint space has no program frame
    return inverse_ ? kNone : forward_->state.line.modal.offset;
}
OrientationMode Translator::mode() const { return inverse_ ? OrientationMode::Joints : forward_->state.line.modal.mode; }
const Modes& Translator::modes() const { return inverse_ ? inverse_->modes() : forward_->state.line.modal.modes; }

}  // namespace xlate5
