// SPDX-License-Identifier: GPL-3.0-or-later
// The inverse direction's pipeline: joint-space lines -> FK -> tool emitter.
// What it may call: see inverse.hpp.
#include "translators/inspect/inverse.hpp"

#include "translators/error.hpp"
#include "translators/pipeline/joint_limits.hpp"
#include "translators/number.hpp"
#include "translators/pipeline/commands.hpp"  // extrudes()

#include <algorithm>
#include <cmath>

namespace xlate5 {

InverseTranslator::InverseTranslator(const Kinematics& kinematics, std::string input_name, char extruder_letter,
                                     OrientationMode preview_form)
    : kin_(kinematics),
      machine_(kinematics.machine()),
      words_(kinematics.machine(), std::move(input_name)),
      extruder_letter_(extruder_letter),
      emitter_(kinematics.machine(), preview_form),
      sent_q_(machine_.home_joints()),
      q_next_(sent_q_) {
    state_.q = machine_.home_joints();
    state_.pose = kin_.forward(state_.q);
    saved_ = state_;
    move_letters_ = "XYZIJKEF";
    for (const Joint& j : machine_.joints) {
        move_letters_ += j.output;
        position_letters_ += j.output;
    }
    position_letters_ += "XYZ";
}

int JointWords::joint_of(char letter) const {
    for (std::size_t j = 0; j < machine_.joints.size(); ++j)
        if (machine_.joints[j].output == letter) return int(j);
    return -1;
}

void JointWords::fail(std::uint32_t column, const std::string& message) const {
    throw InputError(input_name_, line_no_, column, message);
}

double JointWords::number(const Param& p) const {
    if (!p.has_value) fail(p.column, std::string("word ") + p.letter + " has no number");
    return p.value;
}

PassedNumber JointWords::passed(const Param& p, bool inches) const {
    const double v = number(p);
    if (inches) return {v * 25.4, {}};
    return {v, p.text};
}

void InverseTranslator::feed(std::string_view line, std::uint64_t line_no, std::string& out) {
    words_.at_line(line_no);
    try {
        lex_line(line, block_);
        if (block_.empty()) {
            append_wordless(out, line, block_);
            return;
        }
        read_commands(block_, extruder_letter_, commands_);
        plan_line(commands_, state_.modes.motion, move_letters_, position_letters_, plan_);
    } catch (const LineError& e) {
        throw InputError(words_.input_name(), line_no, e.column(), e.what());
    }
    const std::size_t out_start = out.size();
    saved_ = state_;
    try {
        for (std::size_t i = 0; i < plan_.count; ++i) {
            const LineStep& step = plan_.steps[i];
            if (step.command.modal_only()) apply_modal(step.command.code10, step.command.column, step.words, out);
            else run_command(step.command, block_.body, step.verbatim, step.words, out);
        }
    } catch (const LineError& e) {  // a value that cannot be written, from the tool emitter
        out.resize(out_start);
        state_ = saved_;
        throw InputError(words_.input_name(), line_no, e.column(), e.what());
    } catch (...) {
        out.resize(out_start);
        state_ = saved_;
        throw;
    }
}

void InverseTranslator::apply_modal(int code10, std::uint32_t column, Params words, std::string& out) {
    Modes& modes = state_.modes;
    switch (code10) {
        case 200:
        case 210:
            modes.inches = code10 == 200;
            out += "G21\n";
            return;
        case 170:
        case 180:
        case 190:
            modes.plane = code10 / 10;
            append_passthrough(out, 'G', code10, {}, false, words);
            return;
        case 490:
            // G49 (tool-centre-point control and tool length compensation off) says the words are
            // joint values: what this input is already. Nothing to change, nothing written (the
            // output is tool space, where a G49 would switch its reader to joints).
            return;
        case 434:
        case 435:
            fail(column, "joint-space input has no G43.4/G43.5: its words are joint values (G49); the inverse reads the "
                         "firmware's joints, not tool space");
        case 900:
        case 910:
            modes.absolute = code10 == 900;
            modes.e_relative = code10 == 910;
            out += modes.e_relative ? "G90\nM83\n" : "G90\nM82\n";
            return;
        case 930:
        case 940:
            modes.inverse_time = code10 == 930;
            append_passthrough(out, 'G', code10, {}, false, words);
            return;
        default:
            append_passthrough(out, 'G', code10, {}, false, words);
            return;
    }
}

void InverseTranslator::run_command(const CommandWord& c, std::string_view body, bool alone, Params words, std::string& out) {
    Modes& modes = state_.modes;
    if (pass_non_g(c, body, alone, words, modes, out)) return;
    switch (c.code10) {
        case 0:
        case 10:
            modes.motion = c.code10 / 10;
            move(c.code10 / 10, words, out);
            return;
        case 20:
        case 30:
            modes.motion = c.code10 / 10;
            if (!modes.absolute || modes.inches) fail(c.column, "joint-space arcs are passed on only in G90 and G21 (millimetres)");
            fail(c.column, "joint-space arcs cannot be turned back into tool space");
        case 280:
            home(words, out);
            return;
        case 920:
            set_position(words, body, out);
            return;
        default:
            append_passthrough(out, 'G', c.code10, body, alone, words);
            return;
    }
}

namespace {

// Digits after the point of a number as written (0 for a computed one: its parts get three).
int decimals_of(const PassedNumber& n) { return std::max(0, plain_decimals(n.text)); }

// A part's E: three decimals more than written, within what a written number may carry.
constexpr int kMaxPartDecimals = 12;
int part_decimals(const PassedNumber& n) { return std::min(decimals_of(n) + 3, kMaxPartDecimals); }

double rounded(double v, int decimals) {
    const double scale = std::pow(10.0, decimals);
    return std::round(v * scale) / scale;
}

// The last of a retargeted move's n parts takes E's rest (relative E); under absolute E it
// ends at E as written.
std::optional<PassedNumber> last_part_e(const Modes& modes, int n, const std::optional<PassedNumber>& e) {
    if (!e || !modes.e_relative) return e;
    const int d = part_decimals(*e);
    return PassedNumber{rounded(e->value - (n - 1) * rounded(e->value / n, d), d), {}, d};
}

// Each part's F: under G93 the whole move's rate times n (each part takes 1/n of its time).
std::optional<PassedNumber> part_f(const Modes& modes, int n, const std::optional<PassedNumber>& f) {
    if (!f || !modes.inverse_time || n == 1) return f;
    return PassedNumber{f->value * n, {}, std::min(decimals_of(*f), kMaxPartDecimals)};
}

}  // namespace

void InverseTranslator::move(int gcode, Params words, std::string& out) {
    Modes& modes = state_.modes;
    const double unit = modes.unit();
    std::optional<PassedNumber> e, f;
    // The inverse works on what the firmware was sent; words left out keep their sent value.
    q_next_ = sent_q_;
    for (const Param& p : words) {
        switch (p.letter) {
            case 'E': e = words_.passed(p, state_.modes.inches); break;
            case 'F':
                f = words_.passed(p, state_.modes.inches);
                if (!(f->value > 0)) fail(p.column, "feed rate F must be positive");
                break;
            case 'I': case 'J': case 'K':
                fail(p.column, "I J K are tool-vector words (G43.5); under G49 the words are joint values");
            default: {
                const int j = words_.joint_of(p.letter);
                if (j < 0) fail(p.column, std::string("word ") + p.letter + " is not a joint of machine " + machine_.name);
                const bool rotary = machine_.joints[std::size_t(j)].rotary;
                const double v = words_.number(p) * (rotary ? 1.0 : unit);
                q_next_[std::size_t(j)] = modes.absolute ? v : state_.q[std::size_t(j)] + v;
                break;
            }
        }
    }
    // Measured errors are added back to what the firmware was sent.
    sent_q_ = q_next_;
    machine_.compensation.undo(q_next_);
    if (auto r = check_limits(machine_, q_next_); !r.ok()) fail(words.empty() ? 1 : words.front().column, r.message);
    state_.q.swap(q_next_);
    state_.pose = kin_.forward(state_.q);
    const bool travel = !extrudes(e, modes.e_relative, modes.e_position);
    if (retarget_) {
        // The source machine moves its joints linearly: its tip and tool axis follow that path,
        // not the straight line and great arc between the ends. Cut where they part.
        const int n = retarget_->source_pieces(kin_, q_next_, state_.q, travel);
        if (n > 1) source_parts(gcode, n, travel, e, f, out);
        const Pose placed = retarget_->place(state_.pose, travel, words_.line());
        emitter_.move(out, gcode, placed.tip, placed.axis, state_.q, n > 1 ? last_part_e(modes, n, e) : e,
                      n > 1 && !modes.inverse_time ? std::nullopt : part_f(modes, n, f));
    } else {
        emitter_.move(out, gcode, state_.pose.tip, state_.pose.axis, state_.q, e, f);
    }
    if (e) modes.e_position = modes.e_relative ? modes.e_position + e->value : e->value;
}


// The first n - 1 of n equal parts of a retargeted move (the source's joints at k / n): E shared
// out at three more decimals than written (the last part takes the rest, last_part_e), F as
// written on the first (G94; modal after it) or n times it on each (G93: each part takes 1/n of
// the time).
void InverseTranslator::source_parts(int gcode, int n, bool travel, const std::optional<PassedNumber>& e,
                                     const std::optional<PassedNumber>& f, std::string& out) {
    const Modes& modes = state_.modes;
    std::vector<double>& q = part_q_;
    q = q_next_;
    for (int k = 1; k < n; ++k) {
        const double s = double(k) / n;
        for (std::size_t j = 0; j < q.size(); ++j) q[j] = q_next_[j] + s * (state_.q[j] - q_next_[j]);
        const Pose placed = retarget_->place(kin_.forward(q), travel, words_.line());
        std::optional<PassedNumber> ek;
        if (e) {
            const int d = part_decimals(*e);
            ek = PassedNumber{modes.e_relative ? rounded(e->value / n, d) : rounded(modes.e_position + s * (e->value - modes.e_position), d), {}, d};
        }
        emitter_.move(out, gcode, placed.tip, placed.axis, q, ek, k == 1 || modes.inverse_time ? part_f(modes, n, f) : std::nullopt);
    }
}

void InverseTranslator::set_position(Params words, std::string_view body, std::string& out) {
    if (words.empty()) {
        append_passthrough(out, 'G', 920, body, true, words);
        return;
    }
    const double unit = state_.modes.unit();
    std::optional<PassedNumber> e;
    std::string line = "G92";
    for (const Param& p : words) {
        if (p.letter == 'E') {
            e = words_.passed(p, state_.modes.inches);
            state_.modes.e_position = e->value;
            continue;
        }
        const int j = words_.joint_of(p.letter);
        if (j < 0) fail(p.column, std::string("G92 word ") + p.letter + " is not a joint of machine " + machine_.name);
        const bool rotary = machine_.joints[std::size_t(j)].rotary;
        state_.q[std::size_t(j)] = words_.number(p) * (rotary ? 1.0 : unit);
        sent_q_[std::size_t(j)] = state_.q[std::size_t(j)];
    }
    state_.pose = kin_.forward(state_.q);
    // Tool space has a word for a rotary reset only; a linear one just changes the tip.
    for (std::size_t j = 0; j < machine_.joints.size(); ++j) {
        const Joint& J = machine_.joints[j];
        if (!J.rotary || retarget_) continue;
        bool named = false;
        for (const Param& p : words) named = named || (p.letter != 'E' && words_.joint_of(p.letter) == int(j));
        if (!named) continue;
        line += ' ';
        line += J.name;
        append_fixed(line, state_.q[j], machine_.dialect.rotary_decimals + 2);
    }
    if (e) {
        line += " E";
        append_passed(line, *e);
    }
    if (line.size() > 3) out += line + '\n';
    emitter_.invalidate();
}

void InverseTranslator::home(Params words, std::string& out) {
    std::vector<bool> which(state_.q.size(), words.empty());
    for (const Param& p : words) {
        const int j = words_.joint_of(p.letter);
        if (j < 0) fail(p.column, std::string("G28 word ") + p.letter + " is not a joint of machine " + machine_.name);
        which[std::size_t(j)] = true;
    }
    for (std::size_t j = 0; j < state_.q.size(); ++j)
        if (which[j]) state_.q[j] = machine_.joints[j].home;
    out += "G28";
    if (retarget_) retarget_->homed();
    for (const Param& p : words) {
        if (retarget_) break;
        out += ' ';
        out += machine_.joints[std::size_t(words_.joint_of(p.letter))].name;
    }
    out += '\n';
    sent_q_ = state_.q;
    state_.pose = kin_.forward(state_.q);
    emitter_.invalidate();
}

}  // namespace xlate5
