// SPDX-License-Identifier: GPL-3.0-or-later
// The interpreter stage: words + modal state -> the line's commands (commands.hpp).
// What it may call: see interpreter.hpp.
#include "translators/pipeline/interpreter.hpp"

#include <cmath>
#include <optional>
#include <string>

#include "translators/pipeline/arcs.hpp"
#include "translators/error.hpp"

namespace xlate5 {

namespace {

std::string plane_orientation_error(const WorkPlane& plane) {
    return "orientation words inside a tilted plane (G68.2 on line " + std::to_string(plane.line) +
           ") are ambiguous: the tool axis there is the plane's +Z (G53.1); cancel the plane with G69 to orient the tool";
}

using Effect = cmd::Passthrough::Effect;

[[noreturn]] void fail(std::uint32_t column, const std::string& message) { throw LineError(column, message); }

[[noreturn]] void no_number(const Param& p) { fail(p.column, std::string("word ") + p.letter + " has no number"); }

// The value, or an error if it is a flag. Inline: several words a line.
inline double number(const Param& p) {
    if (!p.has_value) no_number(p);
    return p.value;
}

// E or F, in mm.
PassedNumber passed(const Param& p, bool inches) {
    const double v = number(p);
    if (inches) return {v * 25.4, {}};
    return {v, p.text};
}

}  // namespace

JointLetters::JointLetters(const Machine& machine) {
    for (char letter = 'A'; letter <= 'Z'; ++letter) {
        const int j = machine.joint_index(letter);
        joint[std::size_t(letter - 'A')] = j;
        // (None for a letter a tool move reads otherwise, as its switch does: X Y Z I J K E F.)
        const bool own = std::string_view("XYZIJKEF").find(letter) != std::string_view::npos;
        rotary[std::size_t(letter - 'A')] = !own && j >= 0 && machine.joints[std::size_t(j)].rotary ? j : -1;
    }
    // (A command's numbers are fixed arrays of kMaxJoints; the loader allows five joints.)
    if (machine.joints.size() > kMaxJoints)
        throw MachineError(machine.source_path + ": more joints than the interpreter holds (" + std::to_string(kMaxJoints) + ")");
    for (std::size_t j = 0; j < machine.joints.size(); ++j) (machine.joints[j].rotary ? rotary_joints : linear_joints) |= 1u << j;
}

Interpreter::Interpreter(const Machine& machine, ModalState& state, std::string input_name, char extruder_letter)
    : machine_(machine), state_(state), input_name_(std::move(input_name)), extruder_letter_(extruder_letter), letters_(machine) {
    steps_.move_letters = "XYZIJKEF";
    for (const Joint& j : machine_.joints) {
        steps_.move_letters += j.name;
        steps_.position_letters += j.name;
    }
    steps_.position_letters += "XYZ";
}

PassedNumber Interpreter::passed_e(const Param& p, bool inches) {
    if (!inches) return {number(p), p.text};
    // E read in inches is written in millimetres at the dialect's decimals (v * 25.4 has binary
    // noise in its last digits); relative E carries what the rounding left to the next E, so
    // the written total stays within half a unit of the last decimal of the exact total.
    const int ed = machine_.dialect.extrusion_decimals;
    const double scale = std::pow(10.0, ed);
    Modes& modes = state_.modes;
    const double exact = number(p) * 25.4;
    if (!modes.e_relative) return {std::round(exact * scale) / scale, {}, ed};
    const double want = exact + modes.e_inch_carry;
    const double written = std::round(want * scale) / scale;
    modes.e_inch_carry = want - written;
    return {written, {}, ed};
}

bool is_axis_letter(const Machine& machine, char c) {
    return c == 'X' || c == 'Y' || c == 'Z' || c == 'I' || c == 'J' || c == 'K' || machine.joint_index(c) >= 0;
}

inline void Interpreter::read(std::string_view line, std::uint64_t line_no, bool nul_after) {
    line_ = line;
    try {
        lex_line(line, steps_.block, nul_after);
        if (steps_.block.empty()) return;
        read_commands(steps_.block, extruder_letter_, steps_.commands);
        plan_line(steps_.commands, state_.modes.motion, steps_.move_letters, steps_.position_letters, steps_.plan);
    } catch (const LineError& e) {
        throw InputError(input_name_, line_no, e.column(), e.what());
    }
}

void Interpreter::interpret(std::string_view line, std::uint64_t line_no, cmd::CommandList& out, bool nul_after) {
    read(line, line_no, nul_after);
    out.clear();
    list_ = &out;
    if (steps_.block.empty()) {
        append_wordless(out.text, line_, steps_.block);
        passed_text(0);
        return;
    }
    for (std::size_t i = 0; i < steps_.plan.count; ++i) {
        const LineStep& step = steps_.plan.steps[i];
        const CommandWord& c = step.command;
        ModalState& m = state_;
        if (c.letter == 'G' && (c.code10 == 10 || c.code10 == 0) && m.mode != OrientationMode::Joints) {
            // G0/G1 under tool-centre-point control (most lines): run_command's case, without its call.
            m.modes.motion = c.code10 / 10;
            tool_move(c.code10 / 10, c.column, step.words);
        } else if (c.modal_only()) {
            apply_modal(c.code10, step.words);
        } else {
            run_command(c, steps_.block.body, step.verbatim, step.words, line_no);
        }
    }
}

void Interpreter::passed_text(std::size_t begin, cmd::Passthrough::Effect effect) {
    const std::size_t end = list_->text.size();
    if (end == begin && effect == Effect::None) return;
    list_->commands.emplace_back(cmd::Passthrough{std::uint32_t(begin), std::uint32_t(end), effect});
}

void Interpreter::apply_modal(int code10, Params words) {
    ModalState& m = state_;
    std::string& text = list_->text;
    const std::size_t begin = text.size();
    // A feed mode (or plane) passed on in joint space: the emitter's F follows the mode.
    const Effect feed_mode = m.modes.inverse_time ? Effect::InverseTime : Effect::FeedPerMinute;
    switch (code10) {
        case 200:
        case 210:
            // xlate5 converts to millimetres itself; the firmware always works in mm.
            m.modes.inches = code10 == 200;
            text += "G21\n";
            return passed_text(begin);
        case 170:
        case 180:
        case 190:
            // The arc plane: xlate5 linearises arcs under tool-centre-point control itself.
            m.modes.plane = code10 / 10;
            if (m.mode == OrientationMode::Joints) {
                append_passthrough(text, 'G', code10, {}, false, words);
                passed_text(begin, feed_mode);
            }
            return;
        case 434:
        case 435:
        case 490: {
            const OrientationMode mode = code10 == 434 ? OrientationMode::Angles : code10 == 435 ? OrientationMode::Vector : OrientationMode::Joints;
            if (mode != m.mode) add<cmd::NewMode>();  // entering G43.4: its angles mean the joints as they are
            m.mode = mode;
            return;
        }
        case 900:
        case 910:
            // Joint targets are always written absolute; E keeps the input's mode, stated
            // explicitly because firmwares differ on whether G90/G91 change it.
            m.modes.absolute = code10 == 900;
            m.modes.e_relative = code10 == 910;
            text += m.modes.e_relative ? "G90\nM83\n" : "G90\nM82\n";
            return passed_text(begin);
        case 930:
        case 940:
            // Under tool-centre-point control xlate5 computes every F itself (mm/min), so the
            // input's feed mode is understood here and not sent; in joint space it is passed on.
            m.modes.inverse_time = code10 == 930;
            if (m.mode == OrientationMode::Joints) {
                append_passthrough(text, 'G', code10, {}, false, words);
                passed_text(begin, m.modes.inverse_time ? Effect::InverseTime : Effect::FeedPerMinute);
            }
            return;
        default:
            append_passthrough(text, 'G', code10, {}, false, words);
            return passed_text(begin);
    }
}

void Interpreter::run_command(const CommandWord& c, std::string_view body, bool alone, Params words, std::uint64_t line_no) {
    ModalState& m = state_;
    if (c.letter != 'G') {  // S, M, T: passed on
        const std::size_t begin = list_->text.size();
        pass_non_g(c, body, alone, words, m.modes, list_->text);
        return passed_text(begin);
    }
    switch (c.code10) {
        case 0:
        case 10:
            m.modes.motion = c.code10 / 10;
            if (m.mode == OrientationMode::Joints && m.plane.get().active)
                fail(c.column, "joint moves (G49) inside a tilted plane (G68.2 on line " + std::to_string(m.plane.get().line) +
                                   "): cancel it with G69 first");
            if (m.mode == OrientationMode::Joints) joint_move(c.code10 / 10, words);
            else tool_move(c.code10 / 10, c.column, words);
            return;
        case 20:
        case 30:
            m.modes.motion = c.code10 / 10;
            if (m.mode != OrientationMode::Joints) arc(c.code10 == 20, c.column, words);
            else joint_arc(c.code10, body, alone, words, c.column);
            return;
        case 280:
            return home(words);
        case 531:
        case 682:
        case 690:
            return work_plane_command(c, words, line_no);
        case 920:
            return set_position(words, body);
        default:
            return other_g(c, body, alone, words);
    }
}

// A G code xlate5 does not interpret, passed on: with axis words only in joint space, where the
// firmware then moves somewhere xlate5 cannot follow.
void Interpreter::other_g(const CommandWord& c, std::string_view body, bool alone, Params words) {
    Effect effect = Effect::None;
    for (const auto& p : words) {
        if (!is_axis_letter(machine_, p.letter)) continue;
        if (state_.mode != OrientationMode::Joints) {
            std::string code;
            append_code(code, 'G', c.code10);
            if (c.code10 == 430 || c.code10 == 440)
                fail(p.column, "word " + std::string(1, p.letter) + " on a line with " + code + " (tool length compensation): under "
                               "tool-centre-point control the tool's length is the machine file's and X Y Z already place the tip; "
                               "put the move on a line of its own (" + code + " with its H alone is passed on)");
            if (c.code10 == 530)
                fail(p.column, "word " + std::string(1, p.letter) + " of G53 is a machine coordinate, which tool-centre-point control "
                               "does not have: put G49 before it (G53 and its words are then sent as joint values)");
            fail(c.column, code + " with axis words is not supported under tool-centre-point control "
                                  "(switch to G49 to send it as joint values)");
        }
        effect = Effect::PositionUnknown;
    }
    const std::size_t begin = list_->text.size();
    append_passthrough(list_->text, 'G', c.code10, body, alone, words);
    passed_text(begin, effect);
}

// A joint-space G2/G3, passed on as written: the joints it names end at their values.
void Interpreter::joint_arc(int code10, std::string_view body, bool alone, Params words, std::uint32_t column) {
    const Modes& modes = state_.modes;
    if (!modes.absolute || modes.inches) fail(column, "joint-space arcs are passed on only in G90 and G21 (millimetres)");
    cmd::MovedTo& to = add<cmd::MovedTo>();
    for (const auto& p : words) {
        const int j = letters_.joint_of(p.letter);
        if (j < 0) continue;
        to.q[std::size_t(j)] = number(p);
        to.given |= 1u << j;
    }
    const std::size_t begin = list_->text.size();
    append_passthrough(list_->text, 'G', code10, body, alone, words);
    passed_text(begin);
}

[[gnu::always_inline]] inline bool Interpreter::read_tool_words(Params words, cmd::ToolMove& mv, Eigen::Vector3d& ijk, std::uint32_t& ijk_column) {
    const ModalState& m = state_;
    const bool inches = m.modes.inches;
    const double unit = inches ? 25.4 : 1.0;
    const WorkPlane& plane = m.plane.get();
    bool any_ijk = false;
    const bool angles_allowed = !plane.active && m.mode != OrientationMode::Vector;  // rotary words' own checks pass
    for (const Param& p : words) {
        // X Y Z (three words of most lines) before the switch's jump, as its case did.
        if (const unsigned i = unsigned(p.letter - 'X'); i < 3) {
            mv.xyz.value[i] = number(p) * unit;
            mv.xyz.given |= std::uint8_t(1u << i);
            continue;
        }
        switch (p.letter) {
            case 'I': case 'J': case 'K':
                if (plane.active) fail(p.column, plane_orientation_error(plane));
                if (m.mode != OrientationMode::Vector)
                    fail(p.column, "I J K give a tool vector only under G43.5");
                if (!any_ijk) ijk_column = p.column;
                ijk[p.letter - 'I'] = number(p);
                any_ijk = true;
                break;
            case 'E': mv.e = passed_e(p, inches); break;
            case 'F':
                mv.f = passed(p, inches);
                if (!(mv.f->value > 0)) fail(p.column, "feed rate F must be positive");
                break;
            default: {
                const int j = letters_.rotary_of(p.letter);
                if (j < 0 || !angles_allowed) {
                    // The checks in their order (angles_allowed: neither of the last two fails).
                    if (j < 0)
                        fail(p.column, std::string("word ") + p.letter + " is not a tool-space word for machine " + machine_.name +
                                           " (X Y Z give the tip" + (m.mode == OrientationMode::Vector ? ", I J K the tool axis)" : ", its rotary letters the orientation)"));
                    if (plane.active) fail(p.column, plane_orientation_error(plane));
                    if (m.mode == OrientationMode::Vector)
                        fail(p.column, std::string("rotary word ") + p.letter + " under G43.5: give the tool axis as I J K, or switch to G43.4");
                }
                mv.angles[std::size_t(j)] = number(p);
                mv.angles_given |= 1u << j;
                break;
            }
        }
    }
    return any_ijk;
}

void Interpreter::tool_move(int gcode, std::uint32_t column, Params words) {
    ModalState& m = state_;
    const WorkPlane& plane = m.plane.get();
    cmd::ToolMove& mv = add<cmd::ToolMove>();
    Eigen::Vector3d ijk = Eigen::Vector3d::Zero();
    std::uint32_t ijk_column = column;
    bool any_ijk = read_tool_words(words, mv, ijk, ijk_column);
    if (any_ijk) {
        if (!(ijk.norm() > 1e-12)) fail(ijk_column, "tool vector I J K has length 0");
        mv.axis = ijk.normalized();
    }
    mv.mode = m.mode;
    // Under G43.4 the rotary words are programmed angles; the joints are their image. Under G43.5
    // nothing reads them (rotary words are refused, the planner reads angles under G43.4 only,
    // and the keep-out stage refuses G43.5): they are not made on every line.
    mv.reads_angles = m.mode != OrientationMode::Vector;
    if (plane.active && plane.tool_turned) {
        // After G53.1 every move inside the plane holds the tool on the plane's +Z.
        any_ijk = true;
        mv.axis = plane.normal();
        mv.mode = OrientationMode::Vector;
    }
    cmd::JointBits commanded = mv.angles_given;
    if (mv.any_xyz()) commanded |= letters_.linear_joints;
    if (any_ijk) commanded |= letters_.rotary_joints;
    if (mv.f && !m.modes.inverse_time) m.modes.feed = mv.f->value;
    // G93 gives feed moves their duration; a rapid has none (RS274/NGC), so G0 needs no F.
    if (m.modes.inverse_time && !mv.f && gcode != 0 && (mv.any_xyz() || mv.any_rotary() || any_ijk))
        fail(column, "under G93 every feed move (G1, G2, G3) needs its F (1/minutes)");
    mv.gcode = gcode;
    mv.column = column;
    mv.xyz.relative = mv.angles_relative = !m.modes.absolute;
    if (plane.active) mv.plane = plane;
    mv.any_ijk = any_ijk;
    mv.commanded = commanded;
    mv.e_relative = m.modes.e_relative;
    mv.feed = m.modes.feed;
    mv.inverse_time = m.modes.inverse_time;
}

bool Interpreter::read_arc_words(Params words, cmd::Arc& a, std::optional<Param>& e, std::optional<Param>& f) {
    const ModalState& m = state_;
    const double unit = m.modes.unit();
    const ArcPlane plane = arc_plane(m.modes.plane);
    bool centre = false;
    for (const Param& p : words) {
        switch (p.letter) {
            case 'X': case 'Y': case 'Z': {
                const int i = p.letter - 'X';
                a.end.value[std::size_t(i)] = number(p) * unit;
                a.end.given |= std::uint8_t(1u << i);
                break;
            }
            case 'I': case 'J': case 'K':
                if (p.letter == plane.ca) a.offset_a = number(p) * unit, centre = true;
                else if (p.letter == plane.cb) a.offset_b = number(p) * unit, centre = true;
                else fail(p.column, std::string("word ") + p.letter + " is not a centre offset in this arc plane");
                break;
            case 'R': a.radius = number(p) * unit, a.by_radius = true; break;
            case 'P': {
                const double v = number(p);
                if (v < 1 || v > kMaxArcTurns || v != std::floor(v))
                    fail(p.column, "P (turns) must be a whole number from 1 to " + std::to_string(kMaxArcTurns));
                a.turns = int(v);
                break;
            }
            case 'E': e = p; break;
            case 'F': f = p; break;
            default: {
                const int j = letters_.joint_of(p.letter);
                if (j < 0 || !machine_.joints[std::size_t(j)].rotary || m.mode != OrientationMode::Angles)
                    fail(p.column, std::string("word ") + p.letter + " is not understood on an arc here");
                a.angles[std::size_t(j)] = number(p);
                a.angles_given |= 1u << j;
            }
        }
    }
    return centre;
}

// G2/G3 under tool-centre-point control: the arc (I J K centre or R radius, any plane, helical
// along the plane's normal, P full turns), cut into chords by the planner from where the tool is
// (resolve.hpp); each chord is then a move like any other. Under G43.4 rotary words turn
// linearly along the arc. Inside a tilted plane the arc and its G17-G19 are the plane's.
void Interpreter::arc(bool clockwise, std::uint32_t column, Params words) {
    ModalState& m = state_;
    const Modes& modes = m.modes;
    const WorkPlane& plane = m.plane.get();
    cmd::Arc& a = add<cmd::Arc>();
    a.column = column;
    a.clockwise = clockwise;
    a.plane = modes.plane;
    std::optional<Param> e_word, f_word;
    if (read_arc_words(words, a, e_word, f_word) == a.by_radius)
        fail(column, "an arc needs its centre as I J K offsets or its radius as R (one of them)");
    // The chords' own words, checked here once: rotary words (each chord's) and F (the first's).
    if (a.angles_given && plane.active) fail(column, plane_orientation_error(plane));
    if (f_word) {
        a.f = passed(*f_word, modes.inches);
        if (!(a.f->value > 0)) fail(f_word->column, "feed rate F must be positive");
        if (!modes.inverse_time) m.modes.feed = a.f->value;
    }
    if (e_word) {
        // E (mm) to spread over the chords; its text, when read in millimetres, for the last chord's absolute E.
        a.e = PassedNumber{number(*e_word) * modes.unit(), modes.inches ? std::string_view{} : e_word->text};
    }
    a.end.relative = !modes.absolute;
    a.absolute = modes.absolute;
    if (plane.active) a.tilted = plane;
    a.mode = m.mode;
    a.e_relative = modes.e_relative;
    a.feed = m.modes.feed;
    a.inverse_time = modes.inverse_time;
    m.modes.motion = clockwise ? 2 : 3;
}

void Interpreter::joint_move(int gcode, Params words) {
    const Modes& modes = state_.modes;
    const double unit = modes.unit();
    cmd::JointMove& mv = add<cmd::JointMove>();
    for (const Param& p : words) {
        switch (p.letter) {
            case 'E': mv.e = passed_e(p, modes.inches); break;
            case 'F':
                mv.f = passed(p, modes.inches);
                if (!(mv.f->value > 0)) fail(p.column, "feed rate F must be positive");
                break;
            case 'I': case 'J': case 'K':
                fail(p.column, "I J K are tool-vector words (G43.5); under G49 the words are joint values");
            default: {
                const int j = letters_.joint_of(p.letter);
                if (j < 0) fail(p.column, std::string("word ") + p.letter + " is not a joint of machine " + machine_.name);
                const bool rotary = machine_.joints[std::size_t(j)].rotary;
                mv.q[std::size_t(j)] = number(p) * (rotary ? 1.0 : unit);
                mv.given |= 1u << j;
                mv.any_linear = mv.any_linear || !rotary;
                break;
            }
        }
    }
    mv.gcode = gcode;
    mv.column = words.empty() ? 1 : words.front().column;
    mv.relative = !modes.absolute;
    mv.e_relative = modes.e_relative;
    mv.inverse_time = modes.inverse_time;
}

void Interpreter::set_position(Params words, std::string_view body) {
    if (words.empty()) {
        const std::size_t begin = list_->text.size();
        append_passthrough(list_->text, 'G', 920, body, true, words);
        return passed_text(begin);
    }
    ModalState& m = state_;
    const double unit = m.modes.unit();
    cmd::SetPosition& set = add<cmd::SetPosition>();
    bool any_rotary = false;
    const bool tcp = m.mode != OrientationMode::Joints;
    for (const Param& p : words) {
        if (p.letter == 'E') {
            set.e = passed(p, m.modes.inches);
            continue;
        }
        if (tcp && (p.letter == 'X' || p.letter == 'Y' || p.letter == 'Z')) {
            if (m.plane.get().active)
                fail(p.column, "G92 X Y Z inside a tilted plane (G68.2 on line " + std::to_string(m.plane.get().line) +
                                   "): set the program frame before G68.2, or cancel it with G69 first");
            // Under tool-centre-point control G92 X Y Z shifts the program frame, and is not sent.
            const int i = p.letter - 'X';
            set.xyz[std::size_t(i)] = number(p) * unit;
            set.xyz_given |= std::uint8_t(1u << i);
            continue;
        }
        const int j = letters_.joint_of(p.letter);
        if (j < 0 || (tcp && !machine_.joints[std::size_t(j)].rotary))
            fail(p.column, std::string("G92 word ") + p.letter + " is not a joint of machine " + machine_.name);
        const bool rotary = machine_.joints[std::size_t(j)].rotary;
        set.q[std::size_t(j)] = number(p) * (rotary ? 1.0 : unit);
        set.which |= 1u << j;
        any_rotary = any_rotary || rotary;
    }
    // The machine did not move: its true pose follows from the joints it now says it is at.
    set.pose_from_joints = !tcp || any_rotary;
}

void Interpreter::home(Params words) {
    cmd::Home& h = add<cmd::Home>();
    if (words.empty()) h.which = letters_.linear_joints | letters_.rotary_joints;
    for (const Param& p : words) {
        const int j = letters_.joint_of(p.letter);
        if (j < 0) fail(p.column, std::string("G28 word ") + p.letter + " is not a joint of machine " + machine_.name);
        h.which |= 1u << j;
    }
    std::string& text = list_->text;
    const std::size_t begin = text.size();
    text += "G28";
    for (const Param& p : words) {
        text += ' ';
        text += machine_.joints[std::size_t(letters_.joint_of(p.letter))].output;
    }
    text += '\n';
    passed_text(begin);
}

// G68.2 X Y Z I J K: origin (program frame, the program's unit) and Z-X-Z Euler angles in
// degrees, each 0 when not given (LinuxCNC 2.9's P0 Q313, the only form read). G53.1 turns the
// tool to the plane's +Z about the tip held still (a rapid under tool-centre-point control).
// G69 cancels the plane; the tool stays where it is. None of them is sent to the firmware.
void Interpreter::work_plane_command(const CommandWord& c, Params words, std::uint64_t line_no) {
    ModalState& m = state_;
    const WorkPlane& plane = m.plane.get();  // changed through edit() only (work_plane.hpp)
    const std::string code = c.code10 == 682 ? "G68.2" : c.code10 == 531 ? "G53.1" : "G69";
    if (m.mode == OrientationMode::Joints)
        fail(c.column, code + " needs tool-centre-point control (G43.4 or G43.5), not G49");
    if (c.code10 == 682) return define_plane(c, words, line_no);
    if (!words.empty()) fail(words.front().column, code + " takes no words");
    if (!plane.active) fail(c.column, code + " without a tilted plane: G68.2 defines one first");
    if (c.code10 == 690) {
        m.plane.edit() = WorkPlane{};
        return;
    }
    // G53.1: the rotaries turn, the tip stays.
    cmd::ToolMove& mv = add<cmd::ToolMove>();
    mv.gcode = 0;
    mv.column = c.column;
    mv.mode = OrientationMode::Vector;
    mv.hold_tip = true;
    mv.reads_angles = true;
    mv.any_ijk = true;
    mv.axis = plane.normal();
    mv.commanded = letters_.rotary_joints;
    mv.e_relative = m.modes.e_relative;
    mv.feed = m.modes.feed;
    mv.inverse_time = false;
    m.plane.edit().tool_turned = true;
}

void Interpreter::define_plane(const CommandWord& c, Params words, std::uint64_t line_no) {
    ModalState& m = state_;
    const WorkPlane& plane = m.plane.get();
    if (plane.active)
        fail(c.column, "G68.2 inside a tilted plane (G68.2 on line " + std::to_string(plane.line) +
                           "): planes do not nest, cancel it with G69 first");
    Eigen::Vector3d origin = Eigen::Vector3d::Zero(), angles = Eigen::Vector3d::Zero();
    for (const Param& p : words) {
        const double v = number(p);
        switch (p.letter) {
            case 'X': case 'Y': case 'Z': origin[p.letter - 'X'] = v * m.modes.unit(); break;
            case 'I': case 'J': case 'K':
                if (!(std::abs(v) <= 360.0)) fail(p.column, std::string("G68.2 angle ") + p.letter + " must be within -360..360 degrees");
                angles[p.letter - 'I'] = v;
                break;
            case 'P':
                if (v != 0) fail(p.column, "G68.2 reads Euler angles only (P0)");
                break;
            case 'Q':
                if (v != 313) fail(p.column, "G68.2 reads Z-X-Z Euler angles only (Q313)");
                break;
            default:
                fail(p.column, std::string("word ") + p.letter + " is not a G68.2 word (X Y Z origin, I J K Z-X-Z angles in degrees)");
        }
    }
    WorkPlane& set = m.plane.edit();
    set.active = true;
    set.tool_turned = false;
    set.origin = origin;
    set.rotation = euler_zxz(angles.x(), angles.y(), angles.z());
    set.line = line_no;
}

}  // namespace xlate5
