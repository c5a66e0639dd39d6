// SPDX-License-Identifier: GPL-3.0-or-later
// Calibration, beside the pipeline: measurements -> machine-file values.
// What it may call: see calibration.hpp.
#include "translators/machine/calibration.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <limits>
#include <sstream>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5 {

namespace {

std::string number(double v, const char* format = "%.3g") {
    char buf[64];
    std::snprintf(buf, sizeof buf, format, v);
    return buf;
}

// "the fit's condition number is 3.2e+05, the bound is 100", or its rank deficiency.
std::string condition_text(double condition) {
    if (!std::isfinite(condition)) return "the fit's design matrix is rank-deficient";
    return "the fit's condition number is " + number(condition) + ", the bound is " + number(kMaxCondition);
}

// A singular value distinguishable from rounding of the largest.
bool rank_full(double largest, double smallest, Eigen::Index rows) {
    return smallest > double(std::max<Eigen::Index>(rows, 3)) * std::numeric_limits<double>::epsilon() * largest;
}

void check_finite(std::initializer_list<double> values, const char* what) {
    for (double v : values)
        if (!std::isfinite(v))
            throw CalibrationError(std::string("the fit of ") + what + " gives no finite value: the measurements cannot determine it");
}

}  // namespace

double condition_number(const Eigen::MatrixXd& design) {
    if (design.size() == 0 || !design.allFinite()) return std::numeric_limits<double>::infinity();
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(design);
    const auto& s = svd.singularValues();
    const double smallest = s(s.size() - 1);
    // Rank-deficient: fewer rows than columns, or a singular value at the rounding of the
    // largest (LAPACK's numerical rank: max(rows, cols) * epsilon * largest).
    if (design.cols() > design.rows() || !rank_full(s(0), smallest, design.rows())) return std::numeric_limits<double>::infinity();
    return s(0) / smallest;
}

double equilibrated_condition_number(Eigen::MatrixXd design) {
    for (Eigen::Index c = 0; c < design.cols(); ++c) {
        const double n = design.col(c).norm();
        if (!(n > 0) || !std::isfinite(n)) return std::numeric_limits<double>::infinity();
        design.col(c) /= n;
    }
    return condition_number(design);
}

PlateFit fit_plate(const std::vector<Eigen::Vector3d>& points) {
    // Total least squares: the normal is the direction of least spread about the centroid, the
    // last right singular vector of the centred points. The first two singular values are the
    // spreads along and across the plate: their ratio is how far the points are from a line.
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& p : points) centroid += p;
    centroid /= double(points.size());
    Eigen::MatrixXd centred(static_cast<Eigen::Index>(points.size()), 3);
    for (std::size_t i = 0; i < points.size(); ++i) centred.row(Eigen::Index(i)) = (points[i] - centroid).transpose();
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(centred, Eigen::ComputeThinV);
    const auto& sv = svd.singularValues();
    PlateFit f;
    const double rms = sv(0) / std::sqrt(double(points.size()));
    f.condition = points.size() < 3 || !rank_full(sv(0), sv(1), centred.rows()) ? std::numeric_limits<double>::infinity() : sv(0) / sv(1);
    if (!(rms >= kResolution))
        throw CalibrationError("the " + std::to_string(points.size()) +
                               " points are all the same point: probe three or more points far apart across the plate, e.g. near three of its corners");
    if (!(f.condition <= kMaxCondition))
        throw CalibrationError("the " + std::to_string(points.size()) + " points lie on a line" +
                               (std::isfinite(f.condition) ? ", or nearly (their spread across it is 1/" + number(f.condition) +
                                                                 " of their spread along it, the bound is 1/" + number(kMaxCondition) + ")"
                                                           : std::string()) +
                               ", so the tilt across that line is not measured: probe three or more points spread in both "
                               "directions, e.g. near three corners of the plate");
    Eigen::Vector3d n = svd.matrixV().col(2);
    if (n.z() < 0) n = -n;
    f.normal = n;
    f.rho = std::atan2(n.x(), n.z()) * 180.0 / kPi;
    f.psi = std::atan2(-n.y(), std::hypot(n.x(), n.z())) * 180.0 / kPi;
    for (const auto& p : points) f.residual = std::max(f.residual, std::abs((p - centroid).dot(n)));
    check_finite({f.rho, f.psi, f.residual, n.x(), n.y(), n.z()}, "the plate");
    return f;
}

OffsetFit fit_rotary_offset(const std::vector<Eigen::Vector2d>& yz) {
    // Least-squares line z = a y + b. The intercept is the plate's Z on the A axis (Y = 0), so
    // Y is not centred: touches all far to one side leave the intercept (and with it the slope)
    // poorly determined, and the condition number says so.
    Eigen::MatrixXd A(static_cast<Eigen::Index>(yz.size()), 2);
    Eigen::VectorXd z(static_cast<Eigen::Index>(yz.size()));
    for (std::size_t i = 0; i < yz.size(); ++i) {
        A(Eigen::Index(i), 0) = yz[i].x();
        A(Eigen::Index(i), 1) = 1;
        z(Eigen::Index(i)) = yz[i].y();
    }
    OffsetFit f;
    f.condition = equilibrated_condition_number(A);
    // Scaling the columns makes the test blind to the touches' size: below the resolution they are at one Y.
    if (!(A.col(0).maxCoeff() - A.col(0).minCoeff() >= kResolution)) f.condition = std::numeric_limits<double>::infinity();
    if (!(f.condition <= kMaxCondition))
        throw CalibrationError("the touches cannot separate the tilt from the plate's Z (" + condition_text(f.condition) +
                               "): their Y positions are the same or nearly, or all far to one side of the A axis; touch the plate "
                               "at two or more Y positions on both sides of the axis, as far apart as the plate allows");
    const Eigen::Vector2d ab = A.colPivHouseholderQr().solve(z);
    f.offset_deg = std::atan(ab(0)) * 180.0 / kPi;
    f.z_error = ab(1);
    f.residual = (A * ab - z).cwiseAbs().maxCoeff();
    check_finite({f.offset_deg, f.z_error, f.residual}, "the rotary offset");
    return f;
}

CircleFit fit_circle(const std::vector<Eigen::Vector2d>& pts) {
    // Algebraic fit (x^2 + y^2 = 2 a x + 2 b y + c) about the dots' centroid, in units of their
    // RMS spread (the same scale for x and y, so a turned set of dots is conditioned the same),
    // then a few Gauss-Newton steps on the geometric distances, exact for points on a circle.
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    for (const auto& p : pts) centroid += p;
    centroid /= double(pts.size());
    double spread = 0;
    for (const auto& p : pts) spread += (p - centroid).squaredNorm();
    spread = std::sqrt(spread / double(pts.size()));
    const std::string where = "print or probe three or more dots at angles spread around the turn (0, 90, 180 and 270 degrees)";
    if (!(spread >= kResolution)) throw CalibrationError("the " + std::to_string(pts.size()) + " dots are all in one place: " + where);
    Eigen::MatrixXd A(static_cast<Eigen::Index>(pts.size()), 3);
    Eigen::VectorXd r(static_cast<Eigen::Index>(pts.size()));
    for (std::size_t i = 0; i < pts.size(); ++i) {
        const Eigen::Vector2d u = (pts[i] - centroid) / spread;
        A(Eigen::Index(i), 0) = u.x();
        A(Eigen::Index(i), 1) = u.y();
        A(Eigen::Index(i), 2) = 1;
        r(Eigen::Index(i)) = u.squaredNorm();
    }
    CircleFit f;
    f.condition = condition_number(A);
    if (!(f.condition <= kMaxCondition))
        throw CalibrationError("the " + std::to_string(pts.size()) + " dots lie on a line, or nearly (" + condition_text(f.condition) +
                               "), so no circle's centre is measured: " + where);
    const Eigen::Vector3d s = A.colPivHouseholderQr().solve(r);
    f.centre = centroid + spread * Eigen::Vector2d(s(0) / 2, s(1) / 2);
    f.radius = spread * std::sqrt(std::max(0.0, s(2) + (s.head<2>() / 2).squaredNorm()));
    for (int iter = 0; iter < 5; ++iter) {
        Eigen::MatrixXd J(static_cast<Eigen::Index>(pts.size()), 3);
        Eigen::VectorXd res(static_cast<Eigen::Index>(pts.size()));
        for (std::size_t i = 0; i < pts.size(); ++i) {
            const Eigen::Vector2d d = pts[i] - f.centre;
            const double n = std::max(d.norm(), 1e-12);
            J(Eigen::Index(i), 0) = -d.x() / n;
            J(Eigen::Index(i), 1) = -d.y() / n;
            J(Eigen::Index(i), 2) = -1;
            res(Eigen::Index(i)) = n - f.radius;
        }
        const Eigen::Vector3d step = J.colPivHouseholderQr().solve(-res);
        if (!step.allFinite()) break;
        f.centre += step.head<2>();
        f.radius += step(2);
    }
    for (const auto& p : pts) f.residual = std::max(f.residual, std::abs((p - f.centre).norm() - f.radius));
    check_finite({f.centre.x(), f.centre.y(), f.radius, f.residual}, "the rotation centre");
    return f;
}

ParameterFit fit_parameters(const std::string& text, const std::string& source, const std::vector<std::string>& names,
                            const std::map<std::string, double>& start, const std::vector<std::vector<double>>& joints,
                            const std::vector<Eigen::Vector3d>& tips) {
    std::map<std::string, double> p = start;
    const MachineTemplate file(text, source);
    auto residuals = [&](const std::map<std::string, double>& values) {
        const Machine m = file.build(values);
        const Kinematics k(m);
        Eigen::VectorXd r(static_cast<Eigen::Index>(3 * tips.size()));
        for (std::size_t i = 0; i < tips.size(); ++i) r.segment<3>(Eigen::Index(3 * i)) = k.forward(joints[i]).tip - tips[i];
        return r;
    };
    ParameterFit fit;
    Eigen::MatrixXd J;
    auto jacobian = [&] {
        const Eigen::VectorXd r = residuals(p);
        J.resize(r.size(), static_cast<Eigen::Index>(names.size()));
        for (std::size_t c = 0; c < names.size(); ++c) {
            const double h = 1e-5 * std::max(1.0, std::abs(p[names[c]]));
            auto plus = p, minus = p;
            plus[names[c]] += h;
            minus[names[c]] -= h;
            J.col(Eigen::Index(c)) = (residuals(plus) - residuals(minus)) / (2 * h);
        }
        // The parameters' columns scaled to unit length (their units differ): two parameters
        // that move the tips alike are near-parallel. Scaling is blind to size, so first: a
        // parameter whose unit change moves the tips less than the resolution (RMS) is not measured.
        for (std::size_t c = 0; c < names.size(); ++c)
            if (!(J.col(Eigen::Index(c)).norm() / std::sqrt(double(tips.size())) >= kResolution) || !J.col(Eigen::Index(c)).allFinite())
                throw CalibrationError("the measured tips do not depend on '" + names[c] +
                                       "' at these joint values: measure tips at joint values that move it (see docs/calibration.md), "
                                       "or leave it out of --fit");
        fit.condition = equilibrated_condition_number(J);
        if (!(fit.condition <= kMaxCondition)) {
            // The parameters the weakest direction mixes: the right singular vector of the smallest singular value.
            Eigen::MatrixXd scaled = J;
            for (Eigen::Index c = 0; c < scaled.cols(); ++c) scaled.col(c) /= scaled.col(c).norm();
            const Eigen::JacobiSVD<Eigen::MatrixXd> svd(scaled, Eigen::ComputeThinV);
            const Eigen::VectorXd v = svd.matrixV().col(svd.matrixV().cols() - 1).cwiseAbs();
            std::string mixed;
            for (std::size_t c = 0; c < names.size(); ++c)
                if (v(Eigen::Index(c)) >= 0.2 * v.maxCoeff()) mixed += (mixed.empty() ? "'" : ", '") + names[c] + "'";
            throw CalibrationError("the " + std::to_string(tips.size()) + " measurements cannot tell " + mixed + " apart (" +
                                   condition_text(fit.condition) +
                                   "): measure tips at more joint values, spread over the joints' ranges so each parameter "
                                   "moves the tip its own way, or fit fewer parameters");
        }
        return r;
    };
    bool converged = false;
    double last_step = 0;
    for (fit.iterations = 1; fit.iterations <= 30; ++fit.iterations) {
        const Eigen::VectorXd r = jacobian();
        const Eigen::VectorXd step = J.colPivHouseholderQr().solve(-r);
        if (!step.allFinite()) break;
        for (std::size_t c = 0; c < names.size(); ++c) p[names[c]] += step(Eigen::Index(c));
        last_step = step.norm();
        if (last_step < 1e-10) {
            converged = true;
            break;
        }
    }
    if (!converged) {
        // Gauss-Newton converges in a few steps where the model fits; 30 without settling means
        // it does not (a wrong joint order, a start far from the truth).
        throw CalibrationError("the fit does not settle (the last step changed the parameters by " + number(last_step) +
                               "): check the columns' order (the joints in the machine file's order, then x, y, z) and start "
                               "from values near the machine's (--set)");
    }
    (void)jacobian();  // the condition number at the fitted values, and the same refusal there
    fit.values = p;
    const Eigen::VectorXd r = residuals(p);
    for (std::size_t i = 0; i < tips.size(); ++i) fit.residual = std::max(fit.residual, r.segment<3>(Eigen::Index(3 * i)).norm());
    for (const auto& name : names) check_finite({p.at(name)}, ("'" + name + "'").c_str());
    check_finite({fit.residual}, "the residual");
    return fit;
}

std::string set_parameters(const std::string& text, const std::string& source, const std::map<std::string, double>& values) {
    std::istringstream in(text);
    std::string line, out;
    bool in_parameters = false;
    std::map<std::string, bool> done;
    while (std::getline(in, line)) {
        const auto first = line.find_first_not_of(" \t");
        if (first != std::string::npos && line[first] == '[') in_parameters = line.compare(first, 12, "[parameters]") == 0;
        if (in_parameters && first != std::string::npos) {
            const auto eq = line.find('=', first);
            if (eq != std::string::npos) {
                std::string key = line.substr(first, eq - first);
                while (!key.empty() && (key.back() == ' ' || key.back() == '\t')) key.pop_back();
                if (auto it = values.find(key); it != values.end()) {
                    const auto hash = line.find('#', eq);
                    char buf[64];
                    std::snprintf(buf, sizeof buf, "%.6f", it->second);
                    line = line.substr(0, eq) + "= " + buf + (hash != std::string::npos ? "   " + line.substr(hash) : "");
                    done[key] = true;
                }
            }
        }
        out += line + "\n";
    }
    for (const auto& [k, v] : values)
        if (!done.count(k)) throw MachineError(source + ": [parameters] has no '" + k + "' to set");
    return out;
}

CompensationTerm fit_fourier(const std::vector<double>& angle, const std::vector<double>& error, int order, double& max_residual,
                             double* condition_out) {
    const std::size_t n = angle.size();
    const int cols = 1 + 2 * order;
    Eigen::MatrixXd A(static_cast<Eigen::Index>(n), cols);
    Eigen::VectorXd b(static_cast<Eigen::Index>(n));
    for (std::size_t i = 0; i < n; ++i) {
        A(long(i), 0) = 1;
        for (int k = 1; k <= order; ++k) {
            A(long(i), 2 * k - 1) = std::cos(k * angle[i] * kRadPerDeg);
            A(long(i), 2 * k) = std::sin(k * angle[i] * kRadPerDeg);
        }
        b(long(i)) = error[i];
    }
    // The basis functions share one scale (amplitude 1): the raw basis's condition number.
    const double condition = condition_number(A);
    if (condition_out) *condition_out = condition;
    if (!(condition <= kMaxCondition))
        throw CalibrationError("the " + std::to_string(n) + " angles cannot separate " + std::to_string(order) + " harmonic" +
                               (order == 1 ? "" : "s") + " (" + condition_text(condition) +
                               "): measure at more angles, spread evenly over the turn, or fit fewer harmonics (--order)");
    const Eigen::VectorXd c = A.colPivHouseholderQr().solve(b);
    CompensationTerm t;
    t.kind = CompensationTerm::Kind::Fourier;
    t.a0 = c(0);
    for (int k = 1; k <= order; ++k) {
        t.cosines.push_back(c(2 * k - 1));
        t.sines.push_back(c(2 * k));
    }
    max_residual = (A * c - b).cwiseAbs().maxCoeff();
    check_finite({max_residual}, "the series");
    for (int k = 0; k < 2 * order + 1; ++k) check_finite({c(k)}, "the series");
    return t;
}

}  // namespace xlate5
