#include "translators/emitter.hpp"

#include <limits>

#include "translators/error.hpp"
#include "translators/number.hpp"

namespace xlate5 {

void append_passed(std::string& out, const PassedNumber& n) {
    if (!n.text.empty()) out += n.text;
    else if (n.decimals >= 0) append_fixed(out, n.value, n.decimals);
    else append_shortest(out, n.value);
}

namespace {
// A number that cannot be written names the word it was for.
[[noreturn]] void unwritable(char letter, const UnwritableNumber& e) {
    throw UnwritableNumber(std::string("word ") + letter + ": " + e.what());
}

void append_word(std::string& out, char letter, const PassedNumber& n) {
    out += ' ';
    out += letter;
    try {
        append_passed(out, n);
    } catch (const UnwritableNumber& e) {
        unwritable(letter, e);
    }
}

// E and F end a move line; a line that got no word at all (nothing changed) is taken back.
void finish_move(std::string& out, std::size_t start, std::size_t empty, const std::optional<PassedNumber>& e,
                 const std::optional<PassedNumber>& f) {
    if (e) append_word(out, 'E', *e);
    if (f) append_word(out, 'F', *f);
    if (out.size() == empty) out.resize(start);
    else out += '\n';
}
}  // namespace

JointEmitter::JointEmitter(const Machine& machine)
    : machine_(&machine), last_(machine.joints.size(), 0), known_(machine.joints.size(), false), believed_(machine.home_joints()) {}

int JointEmitter::decimals(std::size_t joint) const {
    return machine_->joints[joint].rotary ? machine_->dialect.rotary_decimals : machine_->dialect.linear_decimals;
}

void JointEmitter::format(std::string& text, std::size_t joint, double value) const {
    try {
        append_fixed(text, value, decimals(joint));
    } catch (const UnwritableNumber& e) {
        unwritable(machine_->joints[joint].output, e);
    }
}

void JointEmitter::append_joint(std::string& out, std::size_t joint, double value) const {
    out += ' ';
    out += machine_->joints[joint].output;
    format(out, joint, value);
}

void JointEmitter::invalidate(const std::vector<double>& q) {
    known_.assign(known_.size(), false);
    believed_ = q;
}

void JointEmitter::move(std::string& out, int gcode, const std::vector<double>& q, const std::vector<bool>& commanded,
                        std::optional<PassedNumber> e, std::optional<PassedNumber> f, bool inverse_time) {
    if (inverse_time != inverse_time_) {
        out += inverse_time ? "G93\n" : "G94\n";
        inverse_time_ = inverse_time;
        last_f_.clear();
    }
    const std::size_t start = out.size();
    out += gcode == 0 ? "G0" : "G1";
    const std::size_t empty = out.size();
    // Measured errors are taken off here, the last step before text, so every piece of every
    // move is corrected and nothing upstream sees anything but nominal joints.
    const std::vector<double>* sent = &q;
    if (!machine_->compensation.empty()) {
        sent_ = q;
        if (auto why = machine_->compensation.apply(sent_); !why.empty()) throw LineError(1, why);
        sent = &sent_;
    }
    for (std::size_t j = 0; j < q.size(); ++j) {
        long long units = 0;
        const int d = decimals(j);
        const bool fast = to_units((*sent)[j], d, units);
        if (!fast) units = std::numeric_limits<long long>::min();  // never equal: always written
        const bool write = known_[j] ? units != last_[j] : (commanded[j] || q[j] != believed_[j]);
        believed_[j] = q[j];
        if (!write) continue;
        last_[j] = units;
        known_[j] = true;
        out += ' ';
        out += machine_->joints[j].output;
        if (fast) append_units(out, units, d);
        else format(out, j, (*sent)[j]);
    }
    if (f && !inverse_time_) {  // under G93 every move carries its own F
        f_text_.clear();
        try {
            append_passed(f_text_, *f);
        } catch (const UnwritableNumber& e) {
            unwritable('F', e);
        }
        if (f_text_ == last_f_) f.reset();
        else last_f_ = f_text_;
    }
    finish_move(out, start, empty, e, f);
}

void JointEmitter::set_position(std::string& out, const std::vector<double>& q, const std::vector<bool>& which,
                                std::optional<PassedNumber> e) {
    const std::vector<double>* sent = &q;
    if (!machine_->compensation.empty()) {
        sent_ = q;
        if (auto why = machine_->compensation.apply(sent_); !why.empty()) throw LineError(1, why);
        sent = &sent_;
    }
    const std::size_t start = out.size();
    out += "G92";
    const std::size_t empty = out.size();
    for (std::size_t j = 0; j < q.size(); ++j) {
        if (!which[j]) continue;
        long long units = 0;
        if (!to_units((*sent)[j], decimals(j), units)) units = std::numeric_limits<long long>::min();
        last_[j] = units;
        known_[j] = true;
        believed_[j] = q[j];
        out += ' ';
        out += machine_->joints[j].output;
        format(out, j, (*sent)[j]);
    }
    if (e) append_word(out, 'E', *e);
    if (out.size() == empty) out.resize(start);
    else out += '\n';
}

}  // namespace xlate5

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
        unwritable(letter, e);
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
            for (int i = 0; i < 3; ++i) word(out, char('I' + i), last_ijk_[i], axis[i], 7);
        } else {
            for (std::size_t j = 0; j < q.size(); ++j)
                if (machine_.joints[j].rotary) word(out, machine_.joints[j].name, last_rotary_[j], q[j], rot);
        }
    }
    finish_move(out, start, empty, e, f);
}

}  // namespace xlate5
