// Calibration, beside the pipeline (`xlate5 calibrate`): measurements -> machine-file values.
// May call: kinematics, the machine data, the compensation tables' form.
#pragma once
#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

#include "translators/compensation.hpp"

namespace xlate5 {

// Plate tilt from probed points of the plate surface (three or more, least squares): the plane
// through them, its upward normal n, and rho = atan2(n_x, n_z), psi = atan2(-n_y, hypot(n_x, n_z))
// (degrees) for the tilt R_y(rho) R_x(psi) of WPI (MQP 2017) eq. 3.13, whose normal is
// (cos psi sin rho, -sin psi, cos psi cos rho). `residual` is the largest point-plane distance.
struct PlateFit {
    double rho = 0, psi = 0;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    double residual = 0;
};
PlateFit fit_plate(const std::vector<Eigen::Vector3d>& points);

// Rotary zero offset (Grutle, Oslo 2015, eq. 5.5, A_offset = atan(Z / Y)) from plate touches at two or
// more points along Y: the slope of Z over Y gives the offset, the intercept the Z-origin error,
// which a single touch (eq. 5.5 as printed) cannot tell apart from a tilt.
struct OffsetFit {
    double offset_deg = 0;   // atan(dZ / dY)
    double z_error = 0;      // Z of the plate at Y = 0
    double residual = 0;
};
OffsetFit fit_rotary_offset(const std::vector<Eigen::Vector2d>& yz);

// Rotation centre from points printed or probed at several angles of a rotary (x, y in its
// plane): the least-squares circle through them.
struct CircleFit {
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    double radius = 0;
    double residual = 0;
};
CircleFit fit_circle(const std::vector<Eigen::Vector2d>& points);

// Machine parameters (pivots, link lengths: la, lb of Andersons (Twente 2023); z_offset of WPI (MQP 2017)) from tip
// positions measured at known joint values, by Gauss-Newton least squares on the machine's own
// FK: any parameters of any machine file. Returns the fitted values and the largest residual.
struct ParameterFit {
    std::map<std::string, double> values;
    double residual = 0;  // mm, largest |FK(q) - measured| after the fit
    int iterations = 0;
};
ParameterFit fit_parameters(const std::string& machine_text, const std::string& source, const std::vector<std::string>& names,
                            const std::map<std::string, double>& start, const std::vector<std::vector<double>>& joints,
                            const std::vector<Eigen::Vector3d>& tips);

// Rewrites `name = value` lines of the [parameters] table in a machine file's text, keeping
// everything else (comments, order). Throws MachineError if a name is not there.
std::string set_parameters(const std::string& toml_text, const std::string& source, const std::map<std::string, double>& values);

// Least-squares Fourier series of `order` harmonics through (angle, error) points, and the
// largest residual: what `xlate5 calibrate fit` prints.
CompensationTerm fit_fourier(const std::vector<double>& angle, const std::vector<double>& error, int order, double& max_residual);

}  // namespace xlate5
