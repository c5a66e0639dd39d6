// SPDX-License-Identifier: GPL-3.0-or-later
// The interpreter stage: words + modal state -> typed moves for the planner.
// What it may call: see interpreter.hpp.
#include "translators/pipeline/interpreter.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <optional>
#include <string>

#include "translators/pipeline/arcs.hpp"
#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/pipeline/keep_out.hpp"

namespace xlate5 {

namespace {

std::string plane_orientation_error(const WorkPlane& plane) {
    return "orientation words inside a tilted plane (G68.2 on line " + std::to_string(plane.line) +
           ") are ambiguous: the tool axis there is the plane's +Z (G53.1); cancel the plane with G69 to orient the tool";
}

// A word of an arc's chord, computed here: its text only where the input's number is passed on.
Param chord_word(char letter, double value, std::uint32_t column, std::string_view text = {}) {
    return {.value = value, .text = text, .column = column, .letter = letter, .has_value = true};
}

}  // namespace

Interpreter::Interpreter(const Kinematics& kinematics, LineState& state, Planner& planner, std::string input_name,
                         char extruder_letter)
    : machine_(kinematics.machine()),
      state_(state),
      planner_(planner),
      input_name_(std::move(input_name)),
      extruder_letter_(extruder_letter),
      saved_(state) {
    long_lines_matter_ = machine_.dialect.firmware == FirmwareDialect::Marlin || machine_.dialect.firmware == FirmwareDialect::MarlinArticulated;
    move_letters_ = "XYZIJKEF";
    for (const Joint& j : machine_.joints) {
        move_letters_ += j.name;
        position_letters_ += j.name;
    }
    position_letters_ += "XYZ";
    for (char letter = 'A'; letter <= 'Z'; ++letter) {
        const int j = machine_.joint_index(letter);
        joint_of_letter_[std::size_t(letter - 'A')] = j;
        // (None for a letter tool_move reads otherwise, as its switch does: X Y Z I J K E F.)
        const bool own = std::string_view("XYZIJKEF").find(letter) != std::string_view::npos;
        rotary_of_letter_[std::size_t(letter - 'A')] = !own && j >= 0 && machine_.joints[std::size_t(j)].rotary ? j : -1;
    }
    // (One bit a joint: the loader allows five joints, the emitter eight.)
    if (machine_.joints.size() > 32) throw MachineError(machine_.source_path + ": more joints than the interpreter holds (32)");
    for (std::size_t j = 0; j < machine_.joints.size(); ++j) (machine_.joints[j].rotary ? rotary_joints_ : linear_joints_) |= 1u << j;
}

void Interpreter::fail(std::uint32_t column, const std::string& message) const { throw LineError(column, message); }

void Interpreter::no_number(const Param& p) const { fail(p.column, std::string("word ") + p.letter + " has no number"); }

PassedNumber Interpreter::passed_e(const Param& p, bool inches) {
    if (!inches) return {number(p), p.text};
    // E read in inches is written in millimetres at the dialect's decimals (v * 25.4 has binary
    // noise in its last digits); relative E carries what the rounding left to the next E, so
    // the written total stays within half a unit of the last decimal of the exact total.
    const int ed = machine_.dialect.extrusion_decimals;
    const double scale = std::pow(10.0, ed);
    Modes& modes = state_.modal.modes;
    const double exact = number(p) * 25.4;
    if (!modes.e_relative) return {std::round(exact * scale) / scale, {}, ed};
    const double want = exact + modes.e_inch_carry;
    const double written = std::round(want * scale) / scale;
    modes.e_inch_carry = want - written;
    return {written, {}, ed};
}

PassedNumber Interpreter::passed(const Param& p, bool inches) const {
    const double v = number(p);
    if (inches) return {v * 25.4, {}};
    return {v, p.text};
}

bool is_axis_letter(const Machine& machine, char c) {
    return c == 'X' || c == 'Y' || c == 'Z' || c == 'I' || c == 'J' || c == 'K' || machine.joint_index(c) >= 0;
}

bool Interpreter::is_axis_letter(char c) const { return xlate5::is_axis_letter(machine_, c); }

void Interpreter::feed_line(std::string_view line, LineRun& run, std::string& out, const LineState* before) {
    state_.collide.line = run.line_no;  // the beads this line lays are its own (collide.hpp)
    try {
        lex_line(line, block_);
        if (block_.empty()) {
            append_wordless(out, line, block_);
            return;
        }
        read_commands(block_, extruder_letter_, commands_);
        plan_line(commands_, state_.modal.modes.motion, move_letters_, position_letters_, plan_);
    } catch (const LineError& e) {
        throw InputError(input_name_, run.line_no, e.column(), e.what());
    }

    // Nothing is written until the whole line has been understood and solved: an error leaves
    // neither output nor state changed by this line.
    const std::size_t out_start = out.size();
    if (!before) {
        saved_ = state_;
        before = &saved_;
    }
    try {
        for (std::size_t i = 0; i < plan_.count; ++i) {
            const LineStep& step = plan_.steps[i];
            const CommandWord& c = step.command;
            ModalState& m = state_.modal;
            if (c.letter == 'G' && (c.code10 == 10 || c.code10 == 0) && m.mode != OrientationMode::Joints) {
                // G0/G1 under tool-centre-point control (most lines): run_command's case, without its call.
                m.modes.motion = c.code10 / 10;
                tool_move(c.code10 / 10, c.column, step.words, m.modes.absolute, m.modes.inches, run, out);
            } else if (c.modal_only()) {
                apply_modal(c.code10, step.words, out);
            } else {
                run_command(c, block_.body, step.verbatim, step.words, run, out);
            }
        }
    } catch (...) {
        // Nothing of a failed line stays: output, joints, pose, modes. What the firmware was
        // told of it is not known either.
        out.resize(out_start);
        state_ = *before;
        planner_.position_unknown();
        try {
            throw;
        } catch (const LineError& e) {
            throw InputError(input_name_, run.line_no, e.column(), e.what());
        }
    }
    // Only output of more than 95 characters can hold a line that long (a cheap test per line).
    if (out.size() - out_start > kMarlinLineChars && long_lines_matter_) {
        try {
            check_line_lengths(out, out_start, line, run.line_no);
        } catch (...) {
            out.resize(out_start);
            state_ = *before;
            planner_.position_unknown();
            throw;
        }
    }
}

void Interpreter::check_line_lengths(std::string& out, std::size_t out_start, std::string_view line, std::uint64_t line_no) {
    std::size_t at = out_start;
    while (at < out.size()) {
        std::size_t nl = out.find('\n', at);
        if (nl == std::string::npos) nl = out.size();
        const std::string_view l(out.data() + at, nl - at);
        const bool display = l.rfind("M117", 0) == 0 || l.rfind("M118", 0) == 0;
        // What Marlin stores: up to a ';' comment (the text of a display or file command is
        // taken whole: xlate5 passes it on as written, ';' and all).
        std::size_t stored = l.size();
        const bool text = display || block_.text_argument;
        if (!text)
            if (const auto semi = l.find(';'); semi != std::string_view::npos) stored = semi;
        if (stored > kMarlinLineChars && !(l.size() > 0 && l.front() == ';')) {
            if (!display) {
                // The column of the input where the 96th character of the written line is, when
                // the line was written as read; else the line's start.
                const auto in_at = line.find(l.substr(0, kMarlinLineChars + 1));
                const std::uint32_t column = in_at == std::string_view::npos ? 1 : std::uint32_t(in_at + kMarlinLineChars + 1);
                throw InputError(input_name_, line_no, column,
                                 "this line would be written with " + std::to_string(stored) + " characters: Marlin reads at most " +
                                     std::to_string(kMarlinLineChars) + " and runs the rest as a line of its own; shorten it");
            }
            // A display text loses its tail; nothing is run from it.
            std::size_t keep = kMarlinLineChars;
            while (keep > 4 && l[keep - 1] == ' ') --keep;
            out.erase(at + keep, nl - (at + keep));
            nl = at + keep;
            if (notice_ && line_no > noticed_line_) {
                noticed_line_ = line_no;
                notice_(input_name_ + ":" + std::to_string(line_no) + ": note: " + std::string(l.substr(0, 4)) + "'s text shortened to " +
                        std::to_string(kMarlinLineChars) + " characters (Marlin reads at most " + std::to_string(kMarlinLineChars) +
                        " a line and would run the rest as a command)");
            }
        }
        at = nl + 1;
    }
}

void Interpreter::apply_modal(int code10, Params words, std::string& out) {
    ModalState& m = state_.modal;
    switch (code10) {
        case 200:
        case 210:
            // xlate5 converts to millimetres itself; the firmware always works in mm.
            m.modes.inches = code10 == 200;
            out += "G21\n";
            return;
        case 170:
        case 180:
        case 190:
            // The arc plane: xlate5 linearises arcs under tool-centre-point control itself.
            m.modes.plane = code10 / 10;
            if (m.mode == OrientationMode::Joints) {
                append_passthrough(out, 'G', code10, {}, false, words);
                planner_.feed_mode_sent(m.modes.inverse_time);
            }
            return;
        case 434:
        case 435:
        case 490: {
            const OrientationMode mode = code10 == 434 ? OrientationMode::Angles : code10 == 435 ? OrientationMode::Vector : OrientationMode::Joints;
            if (mode != m.mode) planner_.reset_angle_image();  // entering G43.4: its angles mean the joints as they are
            m.mode = mode;
            return;
        }
        case 900:
        case 910:
            // Joint targets are always written absolute; E keeps the input's mode, stated
            // explicitly because firmwares differ on whether G90/G91 change it.
            m.modes.absolute = code10 == 900;
            m.modes.e_relative = code10 == 910;
            out += m.modes.e_relative ? "G90\nM83\n" : "G90\nM82\n";
            return;
        case 930:
        case 940:
            // Under tool-centre-point control xlate5 computes every F itself (mm/min), so the
            // input's feed mode is understood here and not sent; in joint space it is passed on.
            m.modes.inverse_time = code10 == 930;
            if (m.mode == OrientationMode::Joints) {
                append_passthrough(out, 'G', code10, {}, false, words);
                planner_.feed_mode_sent(m.modes.inverse_time);
            }
            return;
        default:
            append_passthrough(out, 'G', code10, {}, false, words);
            return;
    }
}

void Interpreter::run_command(const CommandWord& c, std::string_view body, bool alone, Params words, LineRun& run,
                              std::string& out) {
    ModalState& m = state_.modal;
    if (c.letter != 'G' && pass_non_g(c, body, alone, words, m.modes, out)) return;  // (the call only for S, M, T)
    switch (c.code10) {
        case 0:
        case 10:
            m.modes.motion = c.code10 / 10;
            if (m.mode == OrientationMode::Joints && m.plane.get().active)
                fail(c.column, "joint moves (G49) inside a tilted plane (G68.2 on line " + std::to_string(m.plane.get().line) +
                                   "): cancel it with G69 first");
            if (m.mode == OrientationMode::Joints) joint_move(c.code10 / 10, words, out);
            else tool_move(c.code10 / 10, c.column, words, m.modes.absolute, m.modes.inches, run, out);
            return;
        case 20:
        case 30:
            m.modes.motion = c.code10 / 10;
            if (m.mode != OrientationMode::Joints) {
                arc(c.code10 == 20, c.column, words, run, out);
                return;
            }
            if (!m.modes.absolute || m.modes.inches)
                fail(c.column, "joint-space arcs are passed on only in G90 and G21 (millimetres)");
            joints_.assign(state_.planner.q.begin(), state_.planner.q.end());
            for (const auto& p : words) {
                const int j = joint_of(p.letter);
                if (j >= 0) joints_[std::size_t(j)] = number(p);
            }
            planner_.moved_to(joints_);
            append_passthrough(out, 'G', c.code10, body, alone, words);
            return;
        case 280:
            home(words, out);
            return;
        case 531:
        case 682:
        case 690:
            work_plane_command(c, words, run, out);
            return;
        case 920:
            set_position(words, body, out);
            return;
        default:
            for (const auto& p : words) {
                if (!is_axis_letter(p.letter)) continue;
                if (m.mode != OrientationMode::Joints) {
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
                planner_.position_unknown();  // the firmware moves somewhere xlate5 cannot follow
            }
            append_passthrough(out, 'G', c.code10, body, alone, words);
            return;
    }
}

void Interpreter::set_move_commanded(std::uint32_t bits, std::size_t joints) {
    if (joints < 32) bits &= (1u << joints) - 1;  // (the state's joints are the machine's)
    if (move_commanded_.size() != joints) {
        move_commanded_.assign(joints, false);
        move_commanded_bits_ = 0;
    }
    // Only the joints whose flag changed (none on most moves: a program names the same axes).
    for (std::uint32_t change = bits ^ move_commanded_bits_; change != 0; change &= change - 1)
        move_commanded_[std::size_t(std::countr_zero(change))].flip();
    move_commanded_bits_ = bits;
}

void Interpreter::track_extrusion(const std::optional<PassedNumber>& e) {
    if (!e) return;
    Modes& modes = state_.modal.modes;
    modes.e_position = modes.e_relative ? modes.e_position + e->value : e->value;
}

void Interpreter::tool_move(int gcode, std::uint32_t column, Params words, bool absolute, bool inches, LineRun& run,
                            std::string& out) {
    ModalState& m = state_.modal;
    const PlannerState& at = state_.planner;
    const double unit = inches ? 25.4 : 1.0;
    const WorkPlane& plane = m.plane.get();
    // The program frame, or the tilted plane's (input_frame_tip, without the call: most lines
    // are outside any plane).
    Eigen::Vector3d tip = at.pose.tip - m.offset;
    if (plane.active) tip = plane.to_plane(tip);
    Eigen::Vector3d ijk = Eigen::Vector3d::Zero();
    bool any_xyz = false, any_ijk = false, any_rotary = false;
    std::uint32_t ijk_column = column;
    ToolMove mv;  // its E and F are written as the words are read
    std::uint32_t commanded = 0;  // one bit a joint, written to move_commanded_ at the end
    // Under G43.4 the rotary words are programmed angles; the joints are their image. Under G43.5
    // nothing reads them (rotary words are refused, the planner reads angles under G43.4 only,
    // and the keep-out stage refuses G43.5): they are left as they are, not made on every line.
    if (m.mode != OrientationMode::Vector) planner_.programmed_angles(angles_);
    const bool angles_allowed = !plane.active && m.mode != OrientationMode::Vector;  // rotary words' own checks pass
    for (const Param& p : words) {
        // X Y Z (three words of most lines) before the switch's jump, as its case did.
        if (const unsigned i = unsigned(p.letter - 'X'); i < 3) {
            const double v = number(p) * unit;
            tip[i] = absolute ? v : tip[i] + v;
            any_xyz = true;
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
                const int j = rotary_of(p.letter);
                if (j < 0 || !angles_allowed) {
                    // The checks in their order (angles_allowed: neither of the last two fails).
                    if (j < 0)
                        fail(p.column, std::string("word ") + p.letter + " is not a tool-space word for machine " + machine_.name +
                                           " (X Y Z give the tip" + (m.mode == OrientationMode::Vector ? ", I J K the tool axis)" : ", its rotary letters the orientation)"));
                    if (plane.active) fail(p.column, plane_orientation_error(plane));
                    if (m.mode == OrientationMode::Vector)
                        fail(p.column, std::string("rotary word ") + p.letter + " under G43.5: give the tool axis as I J K, or switch to G43.4");
                }
                const double v = number(p);
                angles_[std::size_t(j)] = absolute ? v : angles_[std::size_t(j)] + v;
                commanded |= 1u << j;
                any_rotary = true;
                break;
            }
        }
    }
    mv.axis = at.pose.axis;
    if (any_ijk) {
        if (!(ijk.norm() > 1e-12)) fail(ijk_column, "tool vector I J K has length 0");
        mv.axis = ijk.normalized();
    }
    mv.mode = m.mode;
    if (plane.active && plane.tool_turned) {
        // After G53.1 every move inside the plane holds the tool on the plane's +Z.
        any_ijk = true;
        mv.axis = plane.normal();
        mv.mode = OrientationMode::Vector;
    }
    if (any_xyz) commanded |= linear_joints_;
    if (any_ijk) commanded |= rotary_joints_;
    set_move_commanded(commanded, at.q.size());
    if (mv.f && !m.modes.inverse_time) m.modes.feed = mv.f->value;
    // G93 gives feed moves their duration; a rapid has none (RS274/NGC), so G0 needs no F.
    if (m.modes.inverse_time && !mv.f && gcode != 0 && (any_xyz || any_rotary || any_ijk))
        fail(column, "under G93 every feed move (G1, G2, G3) needs its F (1/minutes)");
    mv.gcode = gcode;
    mv.column = column;
    mv.any_xyz = any_xyz;
    mv.tip = (plane.active ? plane.to_program(tip) : tip) + m.offset;  // part_from_input, without the call
    mv.any_rotary = any_rotary;
    mv.angles = &angles_;
    mv.any_ijk = any_ijk;
    mv.commanded = &move_commanded_;
    mv.e_relative = m.modes.e_relative;
    mv.e_position = m.modes.e_position;
    mv.feed = m.modes.feed;
    mv.inverse_time = m.modes.inverse_time;
    if (keep_out_) keep_out_->tool_move(mv, run, out);
    else planner_.tool_move(mv, run, out);
    track_extrusion(mv.e);
}

// G2/G3 under tool-centre-point control: the arc (I J K centre or R radius, any plane, helical
// along the plane's normal, P full turns) is cut into chords within half the tolerance in tool
// space, the other half left for the motion stage's split; each chord is then a move like any
// other. Under G43.4 rotary words turn linearly along the arc.
void Interpreter::arc(bool clockwise, std::uint32_t column, Params words, LineRun& run, std::string& out) {
    ModalState& m = state_.modal;
    const Modes saved = m.modes;
    const double unit = saved.unit();
    const ArcPlane plane = arc_plane(saved.plane);
    Arc a;
    a.clockwise = clockwise;
    a.plane = saved.plane;
    a.start = input_frame_tip();  // inside a tilted plane, the arc and its G17-G19 are the plane's
    a.end = a.start;
    bool centre = false;
    rotary_words_.clear();
    std::optional<Param> e_word, f_word;
    for (const Param& p : words) {
        switch (p.letter) {
            case 'X': case 'Y': case 'Z': {
                const int i = p.letter - 'X';
                const double v = number(p) * unit;
                a.end[i] = saved.absolute ? v : a.start[i] + v;
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
            case 'E': e_word = p; break;
            case 'F': f_word = p; break;
            default: {
                const int j = joint_of(p.letter);
                if (j < 0 || !machine_.joints[std::size_t(j)].rotary || m.mode != OrientationMode::Angles)
                    fail(p.column, std::string("word ") + p.letter + " is not understood on an arc here");
                rotary_words_.push_back(p);
            }
        }
    }
    if (centre == a.by_radius) fail(column, "an arc needs its centre as I J K offsets or its radius as R (one of them)");
    const int bound = pieces_bound(machine_.motion.max_pieces);
    if (auto why = arc_chords(a, 0.5 * machine_.motion.tolerance, chord_ends_, bound); !why.empty()) fail(column, why);
    const int chords = int(chord_ends_.size());
    // Each chord may be split further: the line's output as a whole is bounded too.
    std::size_t counted = out.size();
    long pieces = 0;

    // Each chord runs through tool_move() as an absolute, metric G1 with its own words.
    planner_.programmed_angles(arc_angles_);  // rotary words are programmed angles
    const std::vector<double>& q_start = arc_angles_;
    const double e_total = e_word ? number(*e_word) * unit : 0.0;
    const double e0 = saved.e_position;
    for (int k = 1; k <= chords; ++k) {
        const double f = double(k) / chords;
        const Eigen::Vector3d& p = chord_ends_[std::size_t(k - 1)];
        chord_words_.clear();
        for (int i = 0; i < 3; ++i) chord_words_.push_back(chord_word(char('X' + i), p[i], column));
        for (const Param& rw : rotary_words_) {
            const int j = joint_of(rw.letter);
            const double target = saved.absolute ? number(rw) : q_start[std::size_t(j)] + number(rw);
            chord_words_.push_back(chord_word(rw.letter, q_start[std::size_t(j)] + (target - q_start[std::size_t(j)]) * f, column));
        }
        if (e_word) {
            double v;
            if (saved.e_relative) v = e_total / chords;  // equal chords: equal shares
            else v = e0 + (e_total - e0) * f;
            const bool last = k == chords;
            chord_words_.push_back(chord_word('E', last && !saved.e_relative ? number(*e_word) * unit : v, e_word->column,
                                              last && !saved.e_relative && !saved.inches ? e_word->text : std::string_view{}));
        }
        if (f_word && k == 1) chord_words_.push_back(*f_word);
        if (f_word && k == 1 && saved.inches) chord_words_.back().value *= 25.4, chord_words_.back().text = {};
        tool_move(1, column, chord_words_, true, false, run, out);
        pieces += std::count(out.begin() + std::ptrdiff_t(counted), out.end(), '\n');
        counted = out.size();
        if (pieces > bound)
            fail(column, "the arc needs more than " + std::to_string(bound) +
                             " output lines to stay within the tolerance (the bound on pieces per input line)");
    }
    m.modes.motion = clockwise ? 2 : 3;
}

void Interpreter::joint_move(int gcode, Params words, std::string& out) {
    const Modes& modes = state_.modal.modes;
    const std::vector<double>& q = state_.planner.q;
    const double unit = modes.unit();
    std::optional<PassedNumber> e, f;
    bool any_linear = false;
    joints_.assign(q.begin(), q.end());
    commanded_.assign(q.size(), false);
    for (const Param& p : words) {
        switch (p.letter) {
            case 'E': e = passed_e(p, modes.inches); break;
            case 'F':
                f = passed(p, modes.inches);
                if (!(f->value > 0)) fail(p.column, "feed rate F must be positive");
                break;
            case 'I': case 'J': case 'K':
                fail(p.column, "I J K are tool-vector words (G43.5); under G49 the words are joint values");
            default: {
                const int j = joint_of(p.letter);
                if (j < 0) fail(p.column, std::string("word ") + p.letter + " is not a joint of machine " + machine_.name);
                const bool rotary = machine_.joints[std::size_t(j)].rotary;
                const double v = number(p) * (rotary ? 1.0 : unit);
                joints_[std::size_t(j)] = modes.absolute ? v : q[std::size_t(j)] + v;
                commanded_[std::size_t(j)] = true;
                any_linear = any_linear || !rotary;
                break;
            }
        }
    }
    JointMove mv;
    mv.gcode = gcode;
    mv.column = words.empty() ? 1 : words.front().column;
    mv.q = &joints_;
    mv.commanded = &commanded_;
    mv.any_linear = any_linear;
    mv.e = e;
    mv.f = f;
    mv.inverse_time = modes.inverse_time;
    planner_.joint_move(mv, out);
    track_extrusion(e);
}

void Interpreter::set_position(Params words, std::string_view body, std::string& out) {
    if (words.empty()) {
        append_passthrough(out, 'G', 920, body, true, words);
        return;
    }
    ModalState& m = state_.modal;
    const double unit = m.modes.unit();
    which_.assign(state_.planner.q.size(), false);
    joints_.assign(state_.planner.q.begin(), state_.planner.q.end());
    std::optional<PassedNumber> e;
    bool any_rotary = false;
    const bool tcp = m.mode != OrientationMode::Joints;
    for (const Param& p : words) {
        if (p.letter == 'E') {
            e = passed(p, m.modes.inches);
            m.modes.e_position = e->value;
            continue;
        }
        if (tcp && (p.letter == 'X' || p.letter == 'Y' || p.letter == 'Z')) {
            if (m.plane.get().active)
                fail(p.column, "G92 X Y Z inside a tilted plane (G68.2 on line " + std::to_string(m.plane.get().line) +
                                   "): set the program frame before G68.2, or cancel it with G69 first");
            continue;  // applied below, after the joints
        }
        const int j = joint_of(p.letter);
        if (j < 0 || (tcp && !machine_.joints[std::size_t(j)].rotary))
            fail(p.column, std::string("G92 word ") + p.letter + " is not a joint of machine " + machine_.name);
        const bool rotary = machine_.joints[std::size_t(j)].rotary;
        joints_[std::size_t(j)] = number(p) * (rotary ? 1.0 : unit);
        which_[std::size_t(j)] = true;
        any_rotary = any_rotary || rotary;
    }
    // The machine did not move: its true pose follows from the joints it now says it is at.
    planner_.set_joints(which_, joints_, !tcp || any_rotary);
    if (tcp) {
        // Under tool-centre-point control G92 X Y Z shifts the program frame, and is not sent.
        for (const Param& p : words) {
            if (p.letter != 'X' && p.letter != 'Y' && p.letter != 'Z') continue;
            const int i = p.letter - 'X';
            m.offset[i] = state_.planner.pose.tip[i] - number(p) * unit;
            planner_.tip_placed();
        }
    }
    planner_.send_position(which_, e, out);
}

void Interpreter::home(Params words, std::string& out) {
    which_.assign(state_.planner.q.size(), words.empty());
    for (const Param& p : words) {
        const int j = joint_of(p.letter);
        if (j < 0) fail(p.column, std::string("G28 word ") + p.letter + " is not a joint of machine " + machine_.name);
        which_[std::size_t(j)] = true;
    }
    planner_.home(which_);
    out += "G28";
    for (const Param& p : words) {
        out += ' ';
        out += machine_.joints[std::size_t(joint_of(p.letter))].output;
    }
    out += '\n';
    state_.modal.offset.setZero();
}

Eigen::Vector3d Interpreter::input_frame_tip() const {
    const ModalState& m = state_.modal;
    const Eigen::Vector3d program = state_.planner.pose.tip - m.offset;
    return m.plane.get().active ? m.plane.get().to_plane(program) : program;
}

Eigen::Vector3d Interpreter::part_from_input(const Eigen::Vector3d& p) const {
    const ModalState& m = state_.modal;
    return (m.plane.get().active ? m.plane.get().to_program(p) : p) + m.offset;
}

// G68.2 X Y Z I J K: origin (program frame, the program's unit) and Z-X-Z Euler angles in
// degrees, each 0 when not given (LinuxCNC 2.9's P0 Q313, the only form read). G53.1 turns the
// tool to the plane's +Z about the tip held still (a rapid under tool-centre-point control).
// G69 cancels the plane; the tool stays where it is. None of them is sent to the firmware.
void Interpreter::work_plane_command(const CommandWord& c, Params words, LineRun& run, std::string& out) {
    ModalState& m = state_.modal;
    const WorkPlane& plane = m.plane.get();  // changed through edit() only (work_plane.hpp)
    const std::string code = c.code10 == 682 ? "G68.2" : c.code10 == 531 ? "G53.1" : "G69";
    if (m.mode == OrientationMode::Joints)
        fail(c.column, code + " needs tool-centre-point control (G43.4 or G43.5), not G49");
    if (c.code10 == 682) {
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
        set.line = run.line_no;
        return;
    }
    if (!words.empty()) fail(words.front().column, code + " takes no words");
    if (!plane.active) fail(c.column, code + " without a tilted plane: G68.2 defines one first");
    if (c.code10 == 690) {
        m.plane.edit() = WorkPlane{};
        return;
    }
    // G53.1: the rotaries turn, the tip stays.
    commanded_.assign(state_.planner.q.size(), false);
    for (std::size_t j = 0; j < commanded_.size(); ++j) commanded_[j] = machine_.joints[j].rotary;
    planner_.programmed_angles(angles_);
    ToolMove mv;
    mv.gcode = 0;
    mv.column = c.column;
    mv.mode = OrientationMode::Vector;
    mv.tip = state_.planner.pose.tip;
    mv.angles = &angles_;
    mv.any_ijk = true;
    mv.axis = plane.normal();
    mv.commanded = &commanded_;
    mv.e_relative = m.modes.e_relative;
    mv.e_position = m.modes.e_position;
    mv.feed = m.modes.feed;
    if (keep_out_) keep_out_->tool_move(mv, run, out);
    else planner_.tool_move(mv, run, out);
    m.plane.edit().tool_turned = true;
}

}  // namespace xlate5
