// Stages 3-4: interprets tool-space G-code (modal state, G43.4/G43.5/
// G49, G90/G91, G20/G21, G92, G28), solves each move with Kinematics and hands joint values to
// the emitter. Lines it does not need to understand pass through unchanged and in order.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "translators/emitter.hpp"
#include "translators/gcode_lexer.hpp"
#include "translators/kinematics.hpp"
#include "translators/machine.hpp"
#include "translators/motion.hpp"
#include "translators/report.hpp"

namespace xlate5 {

struct TranslatorOptions {
    std::string input_name = "<stdin>";            // for error messages
    std::optional<OrientationMode> start_mode;      // overrides the machine file's [input] mode
    char extruder_letter = 'E';                     // input letter that carries extrusion
    // Inverse direction: the input is the firmware's joint-space G-code (its axis letters), the
    // output tool space in `preview_form` (G43.4 angles or G43.5 vector), through FK.
    bool inverse = false;
    OrientationMode preview_form = OrientationMode::Angles;
    DeviationReport* report = nullptr;  // when set, every tool-space move is measured into it
};

// The part of the modal state that the inverse direction shares.
struct Modes {
    bool absolute = true;     // G90 / G91
    bool inches = false;      // G20 / G21
    bool e_relative = false;  // Marlin 2 rule: the latest of G90/G91/M82/M83 decides
    int motion = -1;          // modal G0/G1/G2/G3 (-1: none yet)
    int plane = 17;           // G17 XY, G18 ZX, G19 YZ: the plane of arcs
    bool inverse_time = false;  // G93: F is 1/duration in minutes, per move
    double feed = 0;          // programmed feed (G94), mm/min; 0 until the first F
    double e_position = 0;    // absolute E (for sharing an absolute E among pieces)
    double unit() const { return inches ? 25.4 : 1.0; }
};

class Translator {
public:
    Translator(const Kinematics& kinematics, TranslatorOptions options);

    // Translates one input line (without '\n'), appending zero or more output lines to `out`.
    // Throws InputError naming the file, line and column on input it cannot accept; the state
    // is then unchanged by that line.
    void feed(std::string_view line, std::uint64_t line_no, std::string& out);

    // Look-back for joint limits: the output from the latest travel move on is held (for at most
    // `lines` input lines), so that when a printing move further on would take a bounded rotary
    // past its limit, that travel move can be translated again ending on another solution of its
    // pose (the other branch or another turn) and the printed path stays continuous. 0 (the
    // default): every line's output is appended at once, and only the travel move that itself
    // runs into a limit unwinds. With look-back on, call finish() after the last line.
    void set_lookback(std::size_t lines) { lookback_ = lines; }
    void finish(std::string& out);
    static constexpr std::size_t kDefaultLookback = 2000;

    const std::vector<double>& joints() const { return q_; }
    const Pose& pose() const { return pose_; }            // part frame
    const Eigen::Vector3d& program_offset() const { return offset_; }
    OrientationMode mode() const { return mode_; }
    const Modes& modes() const { return modes_; }

private:
    // Under G43.4 the programmed angles are carried onto the joints through q = sign * a + shift
    // per rotary (in rotary_joints() order): identity until a travel move unwinds onto another
    // turn (shift 360 k) or, where the machine has the flip, the other branch (+180, -1).
    struct AngleImage {
        double sign[2] = {1, 1};
        double shift[2] = {0, 0};
        bool operator==(const AngleImage&) const = default;
    };
    // The state a line can change, for rolling back a failed line and for the look-back checkpoint.
    struct Snapshot {
        explicit Snapshot(const Machine& m) : emitter(m) {}
        std::vector<double> q, sent_q;
        Pose pose;
        Eigen::Vector3d offset = Eigen::Vector3d::Zero();
        bool tip_known = false;
        OrientationMode mode = OrientationMode::Angles;
        Modes modes;
        AngleImage image;
        JointEmitter emitter;
    };
    // A move measured for the report, held with its output until that is released.
    struct PendingMove {
        std::uint64_t line;
        double tip, angle, feed;
        int pieces;
        std::size_t travel_end;  // its rotary travel ends here in pending_travel_
    };
    struct Candidate {
        std::vector<double> q;
        AngleImage image;
    };
    struct Param {
        char letter;
        double value;
        std::uint32_t column;
        bool has_value;
        std::string_view text;
    };
    [[noreturn]] void fail(std::uint32_t column, const std::string& message) const;
    const Param* find(char letter) const;
    double number(const Param& p) const;  // the value, or an error if it is a flag
    PassedNumber passed(const Param& p) const;  // E or F, in mm
    void apply_modal(int code10, std::uint32_t column, std::string& out);
    void run_command(char letter, int code10, std::uint32_t column, std::string_view body, bool alone, std::string& out);
    void feed_line(std::string_view line, std::uint64_t line_no, std::string& out);
    void save(Snapshot& s) const;
    void restore(const Snapshot& s);
    bool unwind_before(std::string_view line, std::uint64_t line_no);
    void release(std::size_t bytes, std::size_t moves, std::string& out);
    void report_move(const MoveResult& m);
    void map_angles(const AngleImage& image, const std::vector<double>& a, std::vector<double>& q) const;
    void unmap_angles(const AngleImage& image, const std::vector<double>& q, std::vector<double>& a) const;
    void end_candidates(const Pose& end, const std::vector<double>& programmed, const std::vector<double>& usual);
    void move(int gcode, std::uint32_t column, std::string& out);
    void arc(bool clockwise, std::uint32_t column, std::string& out);
    void move_joints(int gcode, std::uint32_t column, std::string& out);
    void set_position(std::uint32_t column, std::string& out);
    void home(std::string& out);
    void passthrough(char letter, int code10, std::string_view body, bool alone, std::string& out) const;
    void track_extrusion(const std::optional<PassedNumber>& e);
    bool is_axis_letter(char c) const;
    int joint_of(char letter) const;  // joint named by this input letter, or -1

    const Kinematics& kin_;
    const Machine& machine_;
    TranslatorOptions options_;
    JointEmitter emitter_;
    ToolEmitter tool_emitter_;        // used by the inverse direction
    MotionStage motion_;
    MoveResult move_result_;
    Block block_;
    std::vector<Param> params_;
    std::uint64_t line_no_ = 0;

    std::vector<double> q_;         // joint values the firmware will be at
    std::vector<double> q_next_;    // scratch for the move being solved
    std::vector<double> sent_q_;    // inverse: the joints as the firmware was told them (compensated)
    std::vector<double> q_saved_;   // state before the current line, restored if it fails
    std::vector<bool> commanded_;   // joints the current line names (directly or through the tip)
    Pose pose_;                     // tip and tool axis in the part frame
    Eigen::Vector3d offset_ = Eigen::Vector3d::Zero();  // program frame origin in the part frame (G92)
    bool tip_known_ = false;        // has the program placed the tip since start or G28?
    OrientationMode mode_;
    Modes modes_;
    AngleImage image_;              // G43.4: programmed angles -> joints
    std::vector<double> angles_;    // scratch: programmed angles of the current move

    // Joint limits: where a travel move may end (its pose's solutions inside the limits), and
    // the look-back window (see set_lookback).
    std::vector<Candidate> candidates_;
    bool line_travels_ = false;     // the line just translated was a tool-space travel move
    bool line_hit_limit_ = false;   // the line failed on a joint limit
    int forced_ = -1;               // replaying: the checkpoint's travel move takes candidate forced_
    int chosen_ = -1;               // the candidate the checkpoint's travel move took (-1: its usual end)
    bool forced_missing_ = false;   // there is no candidate forced_
    std::size_t lookback_ = 0;
    bool have_checkpoint_ = false;
    std::uint64_t checkpoint_line_ = 0;
    Snapshot before_line_, checkpoint_;
    std::string window_text_;       // input lines from the checkpoint's travel move on, '\n'-separated
    std::vector<std::uint64_t> window_lines_;
    std::string held_;              // their output, not yet released
    std::vector<PendingMove> pending_;
    std::vector<std::pair<char, double>> pending_travel_;  // rotary travel of the held moves
};

}  // namespace xlate5
