// SPDX-License-Identifier: GPL-3.0-or-later
// Tilted work planes (3+2): the frame G68.2 defines, used by the interpreter stage to read
// X Y Z (and arcs) inside the plane and to give the tool axis the plane's normal (G53.1).
// The one place of the plane's math: Euler angles -> rotation, plane <-> program frame, and a
// build direction -> the angles that give it. Data and pure functions; calls nothing but Eigen.
//
// G68.2 X Y Z I J K as Fanuc defines it and LinuxCNC 2.9's tilted-work-plane remap implements
// it (its default P0, Q313): origin X Y Z in the program frame, then I J K Euler angles in
// degrees, Z-X-Z about the rotating axes: R = Rz(I) Rx(J) Rz(K). A point p written inside the
// plane is origin + R p in the program frame; the plane's +Z (the tool axis after G53.1) is
// R's third column.
#pragma once
#include <cstdint>

#include <Eigen/Core>

namespace xlate5 {

struct WorkPlane {
    bool active = false;      // between G68.2 and G69
    bool tool_turned = false; // G53.1 given: every move inside holds the tool on the plane's +Z
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // program frame
    std::uint64_t line = 0;   // the G68.2's input line, for errors

    // Program frame <-> plane frame (points).
    Eigen::Vector3d to_program(const Eigen::Vector3d& p) const { return origin + rotation * p; }
    Eigen::Vector3d to_plane(const Eigen::Vector3d& p) const { return rotation.transpose() * (p - origin); }
    Eigen::Vector3d normal() const { return rotation.col(2); }
};

// The plane as the interpreter's state holds it. The look-back copies that state with every
// line, and the plane changes only on G68.2, G53.1 and G69 lines: every change takes a stamp
// that no other change in the process has taken, so equal stamps mean equal planes and a copy
// onto a plane with the same stamp copies nothing (a few bytes a line, not the whole plane).
class StampedPlane {
public:
    StampedPlane() = default;
    StampedPlane(const StampedPlane&) = default;
    StampedPlane& operator=(const StampedPlane& o) {
        if (stamp_ != o.stamp_) {
            plane_ = o.plane_;
            stamp_ = o.stamp_;
        }
        return *this;
    }
    const WorkPlane& get() const { return plane_; }
    // The only way to change the plane: takes a new stamp first. Change it at once, and keep
    // no reference past a copy of the state.
    WorkPlane& edit();

private:
    WorkPlane plane_;
    std::uint64_t stamp_ = 0;  // 0: as default-constructed (no plane)
};

// R = Rz(i) Rx(j) Rz(k), angles in degrees.
Eigen::Matrix3d euler_zxz(double i_deg, double j_deg, double k_deg);

// Euler angles (degrees, the third 0) whose plane has `direction` (any length but 0) as its +Z:
// J = the tilt from +Z, I = the azimuth that turns +Z toward it. Straight up gives 0 0 0;
// straight down 0 180 0.
Eigen::Vector3d euler_for_direction(const Eigen::Vector3d& direction);

}  // namespace xlate5
