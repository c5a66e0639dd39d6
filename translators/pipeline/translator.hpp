// SPDX-License-Identifier: GPL-3.0-or-later
// The front door of the library: one object that takes input lines and returns output text.
// Forward (tool space -> joints): interpreter -> planner -> motion -> compensation -> emitter,
// under the look-back. Inverse (options.inverse: joints -> tool space): its own pipeline in
// inverse.cpp. It wires the stages together (the only place that hands one stage's value to the
// next: translator.cpp) and holds no logic of its own.
// May call: every forward stage (it hands each one's output to the next), their state (for the accessors), inverse.
#pragma once
#include <array>
#include <functional>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "translators/pipeline/collide.hpp"
#include "translators/pipeline/interpreter.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/inspect/report.hpp"

namespace xlate5 {

struct KeepOutItems;

struct TranslatorOptions {
    std::string input_name = "<stdin>";            // for error messages
    std::optional<OrientationMode> start_mode;      // overrides the machine file's [input] mode
    char extruder_letter = 'E';                     // input letter that carries extrusion
    // Inverse direction: the input is the firmware's joint-space G-code (its axis letters), the
    // output tool space in `preview_form` (G43.4 angles or G43.5 vector), through FK.
    bool inverse = false;
    OrientationMode preview_form = OrientationMode::Angles;
    // Retargeting (--from): the input is joint-space G-code written for the machine of `from`;
    // its forward kinematics give the tip and tool axis (as the inverse does, in the vector
    // form), which are translated for this machine. Null: the input is tool space.
    const Kinematics* from = nullptr;
    // Retargeting: where the source's part frame lies in this machine's (mm, added to every tip):
    // the part placed elsewhere on this machine's bed than on the source's (--place).
    std::array<double, 3> place{};
    DeviationReport* report = nullptr;  // when set, every tool-space move is measured into it
    const KeepOutItems* keep_out = nullptr;  // when set, R comes from the path and these items (keep_out.hpp)
    // The input is written without blanks from its first line on: "X1.5E-05" is X1.5 and E-05, as
    // after the file's own compact declaration (gcode_lexer.hpp).
    bool compact_words = false;
    // Told what was changed on the way to keep the output runnable (a display text shortened to
    // Marlin's 95 characters); the command line writes it on stderr. Empty: not told.
    std::function<void(const std::string&)> notice;
    // The collision check (collide.hpp), when the machine has [[bodies]]: a colliding piece
    // refuses its line (Refuse), is told and written (Warn), or is not checked (Off).
    CollisionPolicy collision = CollisionPolicy::Refuse;
    std::function<void(const CollisionEvent&)> on_collision;  // told of every collision found
    // Override the machine file's [collision] reroute and lift (a travel that would collide is
    // lifted round it instead of refused).
    std::optional<bool> reroute;
    std::optional<double> lift;
};

class InverseTranslator;
class TravelClamp;

class Translator {
public:
    Translator(const Kinematics& kinematics, TranslatorOptions options);
    ~Translator();
    Translator(const Translator&) = delete;
    Translator& operator=(const Translator&) = delete;

    // Translates one input line (without '\n'), appending zero or more output lines to `out`.
    // Throws InputError naming the file, line and column on input it cannot accept; the state
    // is then unchanged by that line.
    void feed(std::string_view line, std::uint64_t line_no, std::string& out);

    // Look-back for joint limits (see lookback.hpp): the output from the latest travel move on is
    // held for at most `lines` input lines, so that a travel move can be translated again ending
    // on another solution when the printing after it would pass a limit. 0 (the default): every
    // line's output is appended at once. With look-back on, call finish() after the last line.
    // The inverse direction has no look-back. `candidates` (1 to 64, the default) lowers the
    // number of end solutions tried at a travel move (the fuzz harness bounds its work with it).
    void set_lookback(std::size_t lines, int candidates = 64);
    void finish(std::string& out);
    bool holding() const;  // a look-back window is open: finish() would end it
    static constexpr std::size_t kDefaultLookback = 2000;

    // The machine is at joints `q` (nominal: compensation undone), as its firmware reports them,
    // and its extruder at `e` when given: the next move starts there. Joints within `within` of
    // where the translator already has them keep its own (more exact) values. Only between
    // look-back windows (not holding()); the forward direction only.
    void place_at(const std::vector<double>& q, std::optional<double> e, double within);

    const std::vector<double>& joints() const;
    const Pose& pose() const;  // part frame
    const Eigen::Vector3d& program_offset() const;
    OrientationMode mode() const;
    const Modes& modes() const;
    // The collision stage, or null (no bodies, --collision off, the inverse direction).
    CollisionStage* collision();

private:
    struct Forward;
    std::unique_ptr<Forward> forward_;
    std::unique_ptr<InverseTranslator> inverse_;
    // Retargeting: the inverse on the source machine feeds the forward pipeline, through this,
    // each move placed on this machine by the clamp.
    bool retarget_ = false;
    std::unique_ptr<TravelClamp> clamp_;
    std::string between_;
    std::string input_name_;
};

}  // namespace xlate5
