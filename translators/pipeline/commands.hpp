// SPDX-License-Identifier: GPL-3.0-or-later
// The interpreter's output, one value per thing a line asks for (docs/ and PIPELINE.md: the
// one-way pipeline). Each owns its numbers, in fixed arrays sized by the one joint bound
// kMaxJoints. What a move leaves out is "as before", and a relative word is relative to where the
// machine is: the planner, which holds the position (joints, tip, the G92 program frame, E),
// fills them in (resolve.hpp). So the interpreter never reads the planner's state, and a command
// can be held and handed on again. Data only; calls nothing.
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "translators/kinematics/kinematics_types.hpp"
#include "translators/machine/machine.hpp"
#include "translators/number.hpp"
#include "translators/pipeline/work_plane.hpp"

namespace xlate5 {

// Whether a move's E word extrudes: a relative E other than 0, an absolute E other than `position`
// (E0 after E5 extrudes, backwards). A move without E does not.
inline bool extrudes(const std::optional<PassedNumber>& e, bool relative, double position) {
    return e && (relative ? e->value != 0 : e->value != position);
}

}  // namespace xlate5

namespace xlate5::cmd {

using xlate5::JointBits;
using xlate5::Joints;

// X Y Z (mm) as the line gave them, in the frame the input reads them in: the program frame
// (G92's), or inside a tilted plane the plane's. An axis not given is as before.
struct InputPoint {
    std::array<double, 3> value;  // read only where given
    std::uint8_t given = 0;  // one bit an axis
    bool relative = false;   // G91: added to where the tip is
};

// A tool-space move (G0/G1 under G43.4/G43.5, G53.1's turn, each chord of a G2/G3).
struct ToolMove {
    // (Not value-initialised as a whole: the interpreter makes one a line. The members without
    // a default are set by whoever makes one; the numbers are read only where given.)
    ToolMove() {}
    int gcode;
    std::uint32_t column;  // of the command, for errors
    OrientationMode mode;
    InputPoint xyz;
    std::optional<WorkPlane> plane;  // the tilted plane X Y Z are read in (none: the program frame)
    bool hold_tip = false;           // the tip stays where it is (G53.1), whatever the frames
    // Programmed angles (G43.4) of the rotaries the line names, absolute or relative; the others
    // are as before. Made for the planner only when `reads_angles` (not under G43.5, where
    // nothing reads them).
    bool reads_angles;
    Joints angles;  // read only where given
    JointBits angles_given = 0;
    bool angles_relative = false;
    bool any_ijk = false;    // the tool axis is given (else as before)
    Eigen::Vector3d axis;    // unit, when any_ijk
    JointBits commanded;     // joints the line names (directly or through the tip)
    std::optional<PassedNumber> e, f;  // as written (mm)
    bool e_relative;
    double feed;  // programmed feed, mm/min
    bool inverse_time;
    bool any_xyz() const { return xyz.given != 0; }
    bool any_rotary() const { return angles_given != 0; }
};

// A G2/G3 under tool-centre-point control: cut into chords from where the tool is (resolve.hpp),
// each then a ToolMove.
struct Arc {
    std::uint32_t column = 1;
    bool clockwise = false;
    int plane = 17;            // G17-G19
    InputPoint end;            // the input frame's X Y Z, mm
    std::optional<WorkPlane> tilted;
    bool by_radius = false;
    double offset_a = 0, offset_b = 0, radius = 0;
    int turns = 1;
    OrientationMode mode = OrientationMode::Angles;
    // Rotary words (programmed angles, G43.4): turned linearly along the arc.
    Joints angles{};
    JointBits angles_given = 0;
    bool absolute = true;  // G90: X Y Z and the angles
    // E (mm, as written unless converted) and its text, spread over the chords; F on the first.
    std::optional<PassedNumber> e;
    std::optional<PassedNumber> f;
    bool e_relative = false;
    double feed = 0;
    bool inverse_time = false;
};

// A joint-space move (G49): every word a joint value, absolute or relative; the rest as before.
struct JointMove {
    int gcode = 1;
    std::uint32_t column = 1;  // of the first word, for errors
    Joints q{};
    JointBits given = 0;
    bool relative = false;
    bool any_linear = false;
    std::optional<PassedNumber> e, f;
    bool e_relative = false;
    bool inverse_time = false;
};

// A move passed on as written (a joint-space G2/G3): the joints named end at their values.
struct MovedTo {
    Joints q{};
    JointBits given = 0;
};

// G92: the firmware is told the joints in `which` are at `q` (the pose then follows from the
// joints when `pose_from_joints`), and under tool-centre-point control X Y Z set the program
// frame so that the tip is there; E sets the extruder's position.
struct SetPosition {
    Joints q{};
    JointBits which = 0;
    bool pose_from_joints = false;
    std::array<double, 3> xyz{};  // mm
    std::uint8_t xyz_given = 0;
    std::optional<PassedNumber> e;
};

// G28 of the joints in `which` (the text is a Passthrough after it).
struct Home {
    JointBits which = 0;
};

// The orientation mode changed: the programmed angles mean the joints as they are.
struct NewMode {};

// Text passed on to the firmware as it is (the command list's text from `begin` to `end`), and
// what it does there.
struct Passthrough {
    enum class Effect : std::uint8_t { None, PositionUnknown, FeedPerMinute, InverseTime };
    std::uint32_t begin = 0, end = 0;
    Effect effect = Effect::None;
};

using Command = std::variant<ToolMove, Arc, JointMove, MovedTo, SetPosition, Home, NewMode, Passthrough>;

// One line's commands in order, and the text their Passthroughs hold. Reused line after line.
struct CommandList {
    std::vector<Command> commands;
    std::string text;
    void clear() {
        commands.clear();
        text.clear();
    }
    std::string_view text_of(const Passthrough& p) const { return std::string_view(text).substr(p.begin, p.end - p.begin); }
};

}  // namespace xlate5::cmd
