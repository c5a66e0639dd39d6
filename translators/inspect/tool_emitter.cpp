// SPDX-License-Identifier: GPL-3.0-or-later
// The inverse direction's emitter: pose -> tool-space text. What it may call: see tool_emitter.hpp.
#include "translators/inspect/tool_emitter.hpp"

#include "translators/number.hpp"

namespace xlate5 {

ToolEmitter::ToolEmitter(const Machine& machine, OrientationMode form)
    : machine_(machine), form_(form), last_rotary_(machine.joints.size()), last_q_(machine.home_joints()) {}

void ToolEmitter::invalidate() {
    for (auto& s : last_xyz_) s.clear();
    for (auto& s : last_ijk_) s.clear();
    for (auto& s : last_rotary_) s.clear();
}

void ToolEmitter::word(std::string& out, char letter, std::string& last, double value, int decimals) {
    scratch_.clear();
    try {
        append_fixed(scratch_, value, decimals);
    } catch (const UnwritableNumber& e) {
        unwritable_word(letter, e);
    }
    if (scratch_ == last) return;
    last = scratch_;
    out += ' ';
    out += letter;
    out += scratch_;
}

void ToolEmitter::move(std::string& out, int gcode, const Eigen::Vector3d& tip, const Eigen::Vector3d& axis,
                       const std::vector<double>& q, std::optional<PassedNumber> e, std::optional<PassedNumber> f) {
    // One or two decimals more than the joints, so translating the preview back reproduces them.
    const int lin = machine_.dialect.linear_decimals + 2, rot = machine_.dialect.rotary_decimals + 2;
    const std::size_t start = out.size();
    out += gcode == 0 ? "G0" : "G1";
    const std::size_t empty = out.size();
    const bool moves = q != last_q_;
    last_q_ = q;
    if (moves) {
        for (int i = 0; i < 3; ++i) word(out, char('X' + i), last_xyz_[i], tip[i], lin);
        if (form_ == OrientationMode::Vector) {
            // The tool vector is written whole whenever any component changes: a reader takes
            // I J K together as the axis (a lone I0 would read as the vector 0 0 0).
            bool changed = false;
            for (int i = 0; i < 3; ++i) {
                scratch_.clear();
                try {
                    append_fixed(scratch_, axis[i], 7);
                } catch (const UnwritableNumber& e) {
                    unwritable_word(char('I' + i), e);
                }
                changed = changed || scratch_ != last_ijk_[i];
            }
            if (changed)
                for (auto& last : last_ijk_) last.clear();
            for (int i = 0; i < 3; ++i) word(out, char('I' + i), last_ijk_[i], axis[i], 7);
        } else {
            for (std::size_t j = 0; j < q.size(); ++j)
                if (machine_.joints[j].rotary) word(out, machine_.joints[j].name, last_rotary_[j], q[j], rot);
        }
    }
    finish_move(out, start, empty, e, f);
}

}  // namespace xlate5
