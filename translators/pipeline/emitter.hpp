// SPDX-License-Identifier: GPL-3.0-or-later
// The emitter stage, last before the sink: joint values -> firmware G-code text, in the
// machine's axis letters and decimals. It only writes text: the joints arrive solved, split and
// compensated. It remembers what the firmware was last told, so a line names only the joints that
// change. May call: number formatting, firmware_config (Klipper's axis registration).
#pragma once
#include <array>
#include <functional>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "translators/kinematics/kinematics_types.hpp"
#include "translators/machine/machine.hpp"
#include "translators/number.hpp"

namespace xlate5 {

void append_passed(std::string& out, const PassedNumber& n);
// The decimals joint j is printed with, and a value as it is printed there (the split and the
// report measure the path the firmware will really take).
int printed_decimals(const Machine& m, std::size_t j);
double printed_value(const Machine& m, std::size_t j, double v);
// Ends a move line begun at `start` with E and F; a line that got no word after its command
// (`out` still `empty` long: nothing changed) is taken back.
void finish_move(std::string& out, std::size_t start, std::size_t empty, const std::optional<PassedNumber>& e,
                 const std::optional<PassedNumber>& f);

// MAX_CMD_SIZE - 1: the characters Marlin reads of a line (PROTOCOL.md rule 4).
inline constexpr std::size_t kMarlinLineChars = 95;

// Marlin reads a line up to 95 characters and the rest as a new line (PROTOCOL.md rule 4): every
// line of `out` from `start` on is checked. Display text (M117, M118) is shortened, and
// `shortened` told the command (its first four characters); anything else is refused with
// LineError at the column of `input` (the line read) where the 96th character is, when the line
// was written as read. `text_argument`: the input's command takes its text whole, ';' and all.
void fit_marlin_lines(std::string& out, std::size_t start, std::string_view input, bool text_argument,
                      const std::function<void(std::string_view)>& shortened);

// Told of every move piece before it is written (the collision stage, collide.hpp), from the
// joints the firmware is believed at to `to`; it may throw LineError to refuse the piece. And
// of every G92 E (the extruder's position, for absolute E).
class PieceObserver {
public:
    // Told of a piece before it is written. Returns joint vectors to travel through first (a
    // detour: the collision check's re-routed travel, written as G0 lines), or null.
    virtual const std::vector<std::vector<double>>* piece(std::span<const double> from, std::span<const double> to,
                                                          const std::optional<PassedNumber>& e) = 0;
    virtual void e_set(double e) = 0;

protected:
    ~PieceObserver() = default;
};

class JointEmitter {
public:
    explicit JointEmitter(const Machine& machine);
    // "G0"/"G1" with every joint whose printed value changed, then E and F when given. A joint
    // whose firmware position is not known is written when the input commands it (`commanded`)
    // or its value changes. Writes nothing when nothing would change.
    // `inverse_time`: F is 1/minutes (G93, written on every move); the emitter switches the
    // firmware between G93 and G94 as needed. `q` are the nominal joints (what the firmware is
    // believed to be at), `sent` the values written (after the compensation stage; `q` itself
    // when there is none).
    void move(std::string& out, int gcode, std::span<const double> q, std::span<const double> sent,
              JointBits commanded, std::optional<PassedNumber> e, std::optional<PassedNumber> f,
              bool inverse_time = false);

    // "G92" for the joints in `which` (the firmware is told where they are) and E when given.
    void set_position(std::string& out, std::span<const double> q, std::span<const double> sent,
                      JointBits which, std::optional<PassedNumber> e);

    // The firmware's position is not exactly known (start, homing, probing): xlate5 believes it
    // is at `q`. Until written again, a joint is sent only when commanded or changed, so a wrong
    // belief (a machine file's home that differs from the firmware's) never causes a surprise move.
    void invalidate(const std::vector<double>& q);

    // A G93/G94 passed on to the firmware as written (joint space): from now on F is inverse
    // time and written on every move (or feed per minute and written when it changes).
    void feed_mode_sent(bool inverse_time) {
        inverse_time_ = inverse_time;
        last_f_size_ = 0;
    }

    // Every piece is shown to `observer` first (null: none). A copy of the emitter keeps the
    // same observer.
    void set_observer(PieceObserver* observer) { observer_ = observer; }

    // Text passed on to the firmware as it is (a Passthrough command's).
    void pass(std::string& out, std::string_view text) const { out += text; }

    // Appends one joint word (" A12.5") as the emitter would print it.
    void append_joint(std::string& out, std::size_t joint, double value) const;

    // How many move lines (G0/G1) have been written: joins a move's events (report, preview) to
    // the output lines it produced. Part of the state, so a replayed window counts again from its start.
    std::uint64_t moves_written() const { return moves_written_; }

private:
    int decimals(std::size_t joint) const { return decimals_[joint]; }
    void format(std::string& text, std::size_t joint, double value) const;
    // move's parts (emitter.cpp).
    void write_detour(std::string& out, const std::vector<std::vector<double>>& detour, const std::optional<PassedNumber>& f,
                      bool inverse_time);
    char* put_f(std::string& out, char* line, char* p, const PassedNumber& f);

    // Fixed arrays, not vectors: a copy of the emitter (the look-back's, before a line that may
    // travel) is one block of memory.
    const Machine* machine_;  // a pointer, so a copy of the emitter is its whole state
    std::size_t joints_ = 0;
    // Per joint, from the machine: the start of its word (" " and its output letter, stored at
    // once) and its printed decimals (read on every move).
    std::array<std::array<char, 2>, kMaxJoints> word_{};
    std::array<int, kMaxJoints> decimals_{};
    std::array<bool, kMaxJoints> absent_{};  // the machine has no such axis: never written
    // Per joint: a value whose |value * 1000| is below this is written by the inline three-decimal
    // path with no other test (999999.5 for three decimals, the usual; -1 for others: never).
    std::array<double, kMaxJoints> small_below_{};
    // The same for the three-decimal path of values up to a million (a multi-turn rotary):
    // 999999999.5 for three decimals, -1 for others.
    std::array<double, kMaxJoints> wide_below_{};
    // What the firmware was last sent per joint, in units of its last printed digit.
    std::array<long long, kMaxJoints> last_{};
    std::array<bool, kMaxJoints> known_{};       // false: not sent since start, homing or probing
    std::array<double, kMaxJoints> believed_{};  // joint values the firmware is believed to be at
    // F is modal in the firmware: written only when its text changes. The text last written (up
    // to kFText characters; 0: none known, so the next F is written).
    static constexpr std::size_t kFText = 32;
    std::array<char, kFText> last_f_{};
    std::size_t last_f_size_ = 0;
    bool inverse_time_ = false;       // the firmware's feed mode as xlate5 last set it
    std::uint64_t moves_written_ = 0;
    PieceObserver* observer_ = nullptr;
};

}  // namespace xlate5
