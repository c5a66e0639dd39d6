// SPDX-License-Identifier: GPL-3.0-or-later
// Calibration, beside the pipeline (`xlate5 calibrate`): measurements -> machine-file values.
// May call: kinematics, the machine data, the compensation tables' form.
#pragma once
#include <Eigen/Core>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "translators/pipeline/compensation.hpp"

namespace xlate5 {

// Measurements that cannot determine what a fit is asked for (docs/calibration.md, "When
// measurements are refused"): the message says why and what to measure instead.
class CalibrationError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Every fit is a least-squares problem on a design matrix (the plane's centred points, the
// line's or circle's coefficients, the Fourier basis, the FK's Jacobian). Its condition number,
// the largest singular value over the smallest, is how much the fit can magnify an error of the
// measurements; past this bound (or at a rank deficiency) the fit refuses them. With probe
// readings good to about 0.01 mm over spans of 10 to 300 mm (1e-3 to 3e-5 of the span), a
// condition number of 100 can make the fitted values wrong by up to 10 % of their size from
// the readings' resolution alone: the bound, and its derivation, in docs/calibration.md.
inline constexpr double kMaxCondition = 100;

// Measurements closer than this (mm) are one: the least digit a dial gauge or a probe shows. The
// condition numbers are blind to scale, so the geometric fits also need their points this far apart.
inline constexpr double kResolution = 0.001;

// The condition number of `design` (infinity when it is rank-deficient), as scaled: what the
// fits test against kMaxCondition.
double condition_number(const Eigen::MatrixXd& design);
// The same after each column is scaled to unit length: for design matrices whose columns have
// different units (a slope and an intercept, millimetres and degrees), so the units do not count.
double equilibrated_condition_number(Eigen::MatrixXd design);

// The largest measurement table read (docs/limits.md): tens of thousands of measurements.
inline constexpr std::size_t kMaxMeasurementBytes = 1u << 20;

// Plate tilt from probed points of the plate surface (three or more, least squares): the plane
// through them, its upward normal n, and rho = atan2(n_x, n_z), psi = atan2(-n_y, hypot(n_x, n_z))
// (degrees) for the tilt R_y(rho) R_x(psi) of WPI (MQP 2017) eq. 3.13, whose normal is
// (cos psi sin rho, -sin psi, cos psi cos rho). `residual` is the largest point-plane distance.
// `condition` is the spread of the points along their longest direction over their spread
// across it (the centred points' first two singular values): the points must not lie on a line.
// Every fit below throws CalibrationError when its condition number passes kMaxCondition.
struct PlateFit {
    double rho = 0, psi = 0;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    double residual = 0;
    double condition = 0;
};
PlateFit fit_plate(const std::vector<Eigen::Vector3d>& points);

// Rotary zero offset (Grutle, Oslo 2015, eq. 5.5, A_offset = atan(Z / Y)) from plate touches at two or
// more points along Y: the slope of Z over Y gives the offset, the intercept the Z-origin error,
// which a single touch (eq. 5.5 as printed) cannot tell apart from a tilt.
struct OffsetFit {
    double offset_deg = 0;   // atan(dZ / dY)
    double z_error = 0;      // Z of the plate at Y = 0
    double residual = 0;
    double condition = 0;    // of (Y, 1), each column scaled to unit length
};
OffsetFit fit_rotary_offset(const std::vector<Eigen::Vector2d>& yz);

// Rotation centre from points printed or probed at several angles of a rotary (x, y in its
// plane): the least-squares circle through them.
struct CircleFit {
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    double radius = 0;
    double residual = 0;
    double condition = 0;    // of (x, y, 1) about the dots' centroid, x and y in units of their RMS spread
};
CircleFit fit_circle(const std::vector<Eigen::Vector2d>& points);

// Machine parameters (pivots, link lengths: la, lb of Andersons (Twente 2023); z_offset of WPI (MQP 2017)) from tip
// positions measured at known joint values, by Gauss-Newton least squares on the machine's own
// FK: any parameters of any machine file. Returns the fitted values and the largest residual.
struct ParameterFit {
    std::map<std::string, double> values;
    double residual = 0;  // mm, largest |FK(q) - measured| after the fit
    int iterations = 0;
    double condition = 0;  // of the FK's Jacobian by the parameters at the fit, each column scaled to unit length
};
ParameterFit fit_parameters(const std::string& machine_text, const std::string& source, const std::vector<std::string>& names,
                            const std::map<std::string, double>& start, const std::vector<std::vector<double>>& joints,
                            const std::vector<Eigen::Vector3d>& tips);

// Rewrites `name = value` lines of the [parameters] table in a machine file's text, keeping
// everything else (comments, order). Throws MachineError if a name is not there.
std::string set_parameters(const std::string& toml_text, const std::string& source, const std::map<std::string, double>& values);

// Least-squares Fourier series of `order` harmonics through (angle, error) points, and the
// largest residual: what `xlate5 calibrate fit` prints. `condition`, when given, is set to the
// basis's condition number (each column scaled to unit length).
CompensationTerm fit_fourier(const std::vector<double>& angle, const std::vector<double>& error, int order, double& max_residual,
                             double* condition = nullptr);

}  // namespace xlate5
