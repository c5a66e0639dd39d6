// SPDX-License-Identifier: GPL-3.0-or-later
// The emitter stage of the inverse direction (inverse.cpp): tip and orientation -> tool-space
// G-code (G43.4 angle form or G43.5 vector form), for previews and round-trip checks. Only writes
// text. May call: number formatting and the E/F writing it shares with the joint emitter.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "translators/pipeline/emitter.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5 {

class ToolEmitter {
public:
    ToolEmitter(const Machine& machine, OrientationMode form);

    void move(std::string& out, int gcode, const Eigen::Vector3d& tip, const Eigen::Vector3d& axis,
              const std::vector<double>& q, std::optional<PassedNumber> e, std::optional<PassedNumber> f);
    void invalidate();
    OrientationMode form() const { return form_; }

private:
    void word(std::string& out, char letter, std::string& last, double value, int decimals);

    const Machine& machine_;
    OrientationMode form_;
    std::string last_xyz_[3], last_ijk_[3];
    std::vector<std::string> last_rotary_;
    std::vector<double> last_q_;   // joints of the previous move: an unchanged pose writes no words
    std::string scratch_;
};

}  // namespace xlate5
