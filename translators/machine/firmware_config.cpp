// SPDX-License-Identifier: GPL-3.0-or-later
// The firmware's side of a machine file. What it may call: see firmware_config.hpp.
// The syntax of each firmware, as its own documentation gives it: Marlin 2.1's Configuration.h
// (AXISn_NAME, AXISn_ROTATES, *_MIN_POS / *_MAX_POS, DEFAULT_MAX_FEEDRATE in units per second),
// RepRapFirmware's M584 (R1: the axes it creates are rotational, RRF 3.2 and later), M208 (S1
// minima, S0 maxima), M203 (mm or degrees per minute), and Klipper's [manual_stepper]
// (velocity in units per second, position_min / position_max) with MANUAL_STEPPER ...
// GCODE_AXIS=.
#include "translators/machine/firmware_config.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "translators/error.hpp"

namespace xlate5 {

namespace {

// A number as a person writes it: at most four decimals, no trailing zeros.
std::string num(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.4f", v);
    std::string s = buf;
    if (s.find('.') != std::string::npos) {
        while (s.back() == '0') s.pop_back();
        if (s.back() == '.') s.pop_back();
    }
    if (s == "-0") s = "0";
    return s;
}

// An unbounded rotary has no limits in the machine file; the firmware wants some. Past its
// re-zero xlate5 never drives it; without one, a range no print reaches.
double soft_limit(const Joint& j) { return j.rezero_beyond > 0 ? j.rezero_beyond + 360 : 100000; }
double lo(const Joint& j) { return j.bounded() ? j.min : -soft_limit(j); }
double hi(const Joint& j) { return j.bounded() ? j.max : soft_limit(j); }

std::vector<const Joint*> extra_axes(const Machine& m) {
    std::vector<const Joint*> out;
    for (const Joint& j : m.joints)
        if (j.output != 'X' && j.output != 'Y' && j.output != 'Z' && !j.absent) out.push_back(&j);
    return out;
}

const Joint* axis(const Machine& m, char letter) {
    for (const Joint& j : m.joints)
        if (j.output == letter) return &j;
    return nullptr;
}

[[noreturn]] void refuse(const Machine& m, const std::string& why) { throw MachineError(m.source_path + ": " + why); }

void need_xyz(const Machine& m, const char* firmware) {
    for (const char c : {'X', 'Y', 'Z'}) {
        const Joint* j = axis(m, c);
        if (!j || j->rotary)
            refuse(m, std::string(firmware) + " needs linear axes named X, Y and Z (output letters); this machine has " +
                          (j ? std::string("a rotary ") + c : std::string("no ") + c));
    }
}

std::string marlin(const Machine& m) {
    need_xyz(m, "Marlin");
    const auto extra = extra_axes(m);
    static const char kInternal[] = {'I', 'J', 'K', 'U', 'V', 'W'};
    static const std::string kNames = "ABCUVW";
    if (extra.size() > 6) refuse(m, "Marlin takes at most six axes beyond X Y Z");
    std::string o = "// xlate5 firmware-config: machine " + m.name + ", Marlin 2.1 Configuration.h\n";
    o += "// The extra axes in the machine file's order. Marlin names them I J K U V W inside and takes\n";
    o += "// each one's G-code letter from AXISn_NAME (A B C U V W, in that order). Driver types and\n";
    o += "// steps per unit are not in the machine file: set yours.\n";
    std::size_t last = 0;
    for (std::size_t i = 0; i < extra.size(); ++i) {
        const Joint& j = *extra[i];
        const std::size_t at = kNames.find(j.output);
        if (at == std::string::npos || at < i || (i > 0 && at <= last))
            refuse(m, std::string("Marlin cannot name its axis ") + std::to_string(i + 4) + " '" + j.output +
                          "': AXISn_NAME takes A B C U V W in that order, one letter each (AXIS" + std::to_string(i + 4) +
                          "_NAME from " + kNames.substr(i) + ")");
        last = at;
        const std::string n = std::to_string(i + 4);
        o += std::string("#define ") + kInternal[i] + "_DRIVER_TYPE A4988   // yours\n";
        o += "#define AXIS" + n + "_NAME '" + j.output + "'\n";
        if (j.rotary) o += "#define AXIS" + n + "_ROTATES\n";
    }
    o += "\n";
    const auto limits = [&](const std::string& p, const Joint& j) {
        o += "#define " + p + "_MIN_POS " + num(lo(j)) + "\n";
        o += "#define " + p + "_MAX_POS " + num(hi(j)) + "\n";
        if (j.home == j.min) o += "#define " + p + "_HOME_DIR -1\n";
        else if (j.home == j.max) o += "#define " + p + "_HOME_DIR 1\n";
        else o += "// " + p + ": home " + num(j.home) + " is at neither limit: set " + p + "_HOME_DIR and its home position yourself\n";
    };
    for (const char c : {'X', 'Y', 'Z'}) {
        if (axis(m, c)->absent) o += std::string("// ") + c + ": the machine has no such axis (held at " + num(axis(m, c)->home) + ")\n";
        else limits(std::string(1, c), *axis(m, c));
    }
    for (std::size_t i = 0; i < extra.size(); ++i) {
        if (!extra[i]->bounded()) o += std::string("// ") + extra[i]->output + " turns without end in the machine file: limits past its re-zero\n";
        limits(std::string(1, kInternal[i]), *extra[i]);
    }
    o += "\n#define DEFAULT_MAX_FEEDRATE { ";
    std::string order = "X, Y, Z";
    const auto feed = [&](const Joint& j) { o += (j.max_feed > 0 ? num(j.max_feed / 60) : std::string("0 /* not in the machine file */")) + ", "; };
    for (const char c : {'X', 'Y', 'Z'}) feed(*axis(m, c));
    for (const Joint* j : extra) {
        feed(*j);
        order += std::string(", ") + j->output;
    }
    o += "25 }   // " + order + ", E; units per second (degrees for rotaries); E's 25 is Marlin's example: yours\n";
    return o;
}

std::string reprap(const Machine& m) {
    need_xyz(m, "RepRapFirmware");
    const auto extra = extra_axes(m);
    std::string o = "; xlate5 firmware-config: machine " + m.name + ", RepRapFirmware config.g\n";
    o += "; Driver numbers are placeholders, one per axis in the machine file's order, the extruder last:\n";
    o += "; set yours. M584 comes before M92, M203 and M208 (it creates the extra axes).\n";
    int driver = 0;
    std::string first = "M584";
    for (const char c : {'X', 'Y', 'Z'})
        if (!axis(m, c)->absent) first += std::string(" ") + c + std::to_string(driver++);
    std::string created;
    for (const Joint* j : extra) {
        // R applies to every axis one M584 creates: one command per extra axis.
        created += std::string("M584 ") + j->output + std::to_string(driver++) + (j->rotary ? " R1" : " R0") + "   ; " +
                   (j->rotary ? "rotational (degrees)" : "linear (mm)") + "\n";
    }
    o += first + " E" + std::to_string(driver) + "   ; the extruder's driver after the axes'\n" + created;
    o += "M208";
    for (const Joint& j : m.joints)
        if (!j.absent) o += std::string(" ") + j.output + num(lo(j)) + ":" + num(hi(j));
    o += "   ; axis limits, minimum:maximum\n";
    for (const Joint& j : m.joints)
        if (j.rotary && !j.bounded()) o += std::string("; ") + j.output + " turns without end in the machine file: limits past its re-zero\n";
    o += "M203";
    for (const Joint& j : m.joints)
        if (j.max_feed > 0 && !j.absent) o += std::string(" ") + j.output + num(j.max_feed);
    o += "   ; maximum speeds, mm/min and degrees/min\n";
    o += "; M92";
    for (const Joint& j : m.joints)
        if (!j.absent) o += std::string(" ") + j.output + "<steps per " + (j.rotary ? "degree" : "mm") + ">";
    o += "   ; steps per unit are not in the machine file\n";
    return o;
}

std::string klipper(const Machine& m) {
    need_xyz(m, "Klipper");
    const auto extra = extra_axes(m);
    for (const Joint* j : extra)
        if (j->output == 'E' || j->output == 'F')
            refuse(m, std::string("Klipper cannot take ") + j->output + " as an extra G-code axis");
    std::string o = "# xlate5 firmware-config: machine " + m.name + ", Klipper printer.cfg\n";
    o += "# Merge these into your sections: pins, microsteps and rotation_distance are not in the machine\n";
    o += "# file (a rotary's rotation_distance is in degrees per motor turn, with its gear ratio).\n";
    double xy = 0;
    for (const char c : {'X', 'Y'}) xy = std::max(xy, axis(m, c)->max_feed);
    o += "[printer]\n";
    if (xy > 0) o += "max_velocity: " + num(xy / 60) + "\n";
    if (axis(m, 'Z')->max_feed > 0) o += "max_z_velocity: " + num(axis(m, 'Z')->max_feed / 60) + "\n";
    for (const char c : {'X', 'Y', 'Z'}) {
        const Joint& j = *axis(m, c);
        if (j.absent) continue;  // the machine has no such axis
        o += std::string("\n[stepper_") + char(std::tolower(static_cast<unsigned char>(c))) + "]\n";
        o += "position_min: " + num(lo(j)) + "\n";
        o += "position_max: " + num(hi(j)) + "\n";
        if (j.home == j.min || j.home == j.max) o += "position_endstop: " + num(j.home) + "\n";
    }
    for (const Joint* j : extra) {
        o += "\n[manual_stepper " + j->manual_stepper + "]\n";
        if (j->max_feed > 0) o += "velocity: " + num(j->max_feed / 60) + std::string(j->rotary ? "   # degrees/s" : "   # mm/s") + "\n";
        o += "position_min: " + num(lo(*j)) + "\n";
        o += "position_max: " + num(hi(*j)) + "\n";
    }
    if (!extra.empty()) {
        o += "\n[gcode_macro XLATE5_REGISTER_AXES]\n";
        o += "description: the extra axes as G-code axes (xlate5's output starts with the same lines)\n";
        o += "gcode:\n";
        for (const Joint* j : extra) o += "  " + klipper_register(*j);
    }
    return o;
}

}  // namespace

std::string klipper_register(const Joint& j) {
    std::string s = "MANUAL_STEPPER STEPPER=" + j.manual_stepper + " GCODE_AXIS=" + j.output;
    if (j.max_feed > 0) s += " LIMIT_VELOCITY=" + num(j.max_feed / 60);
    return s + "\n";
}

std::string firmware_config(const Machine& machine, FirmwareKind kind) {
    switch (kind) {
        case FirmwareKind::Marlin: return marlin(machine);
        case FirmwareKind::RepRap: return reprap(machine);
        case FirmwareKind::Klipper: return klipper(machine);
    }
    return {};
}

std::string firmware_preamble(const Machine& machine) {
    if (machine.dialect.firmware != FirmwareDialect::Klipper) return {};
    std::string o;
    for (const Joint* j : extra_axes(machine)) o += klipper_register(*j);
    return o;
}

}  // namespace xlate5
