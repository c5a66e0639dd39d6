// Calibration, beside the pipeline: measurements -> machine-file values.
// What it may call: see calibration.hpp.
#include "translators/calibration.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/kinematics.hpp"
#include "translators/machine.hpp"

namespace xlate5 {

PlateFit fit_plate(const std::vector<Eigen::Vector3d>& points) {
    // Total least squares: the normal is the direction of least spread about the centroid.
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& p : points) centroid += p;
    centroid /= double(points.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : points) cov += (p - centroid) * (p - centroid).transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    Eigen::Vector3d n = eig.eigenvectors().col(0);  // smallest eigenvalue first
    if (n.z() < 0) n = -n;
    PlateFit f;
    f.normal = n;
    f.rho = std::atan2(n.x(), n.z()) * 180.0 / kPi;
    f.psi = std::atan2(-n.y(), std::hypot(n.x(), n.z())) * 180.0 / kPi;
    for (const auto& p : points) f.residual = std::max(f.residual, std::abs((p - centroid).dot(n)));
    return f;
}

OffsetFit fit_rotary_offset(const std::vector<Eigen::Vector2d>& yz) {
    // Least-squares line z = a y + b.
    Eigen::MatrixXd A(static_cast<Eigen::Index>(yz.size()), 2);
    Eigen::VectorXd z(static_cast<Eigen::Index>(yz.size()));
    for (std::size_t i = 0; i < yz.size(); ++i) {
        A(Eigen::Index(i), 0) = yz[i].x();
        A(Eigen::Index(i), 1) = 1;
        z(Eigen::Index(i)) = yz[i].y();
    }
    const Eigen::Vector2d ab = A.colPivHouseholderQr().solve(z);
    OffsetFit f;
    f.offset_deg = std::atan(ab(0)) * 180.0 / kPi;
    f.z_error = ab(1);
    f.residual = (A * ab - z).cwiseAbs().maxCoeff();
    return f;
}

CircleFit fit_circle(const std::vector<Eigen::Vector2d>& pts) {
    // Algebraic fit (x^2 + y^2 = 2 a x + 2 b y + c), then one Gauss-Newton refinement of the
    // geometric distances, which is exact for points on a circle.
    Eigen::MatrixXd A(static_cast<Eigen::Index>(pts.size()), 3);
    Eigen::VectorXd r(static_cast<Eigen::Index>(pts.size()));
    for (std::size_t i = 0; i < pts.size(); ++i) {
        A(Eigen::Index(i), 0) = 2 * pts[i].x();
        A(Eigen::Index(i), 1) = 2 * pts[i].y();
        A(Eigen::Index(i), 2) = 1;
        r(Eigen::Index(i)) = pts[i].squaredNorm();
    }
    const Eigen::Vector3d s = A.colPivHouseholderQr().solve(r);
    CircleFit f;
    f.centre = Eigen::Vector2d(s(0), s(1));
    f.radius = std::sqrt(std::max(0.0, s(2) + f.centre.squaredNorm()));
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
        f.centre += step.head<2>();
        f.radius += step(2);
    }
    for (const auto& p : pts) f.residual = std::max(f.residual, std::abs((p - f.centre).norm() - f.radius));
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
    for (fit.iterations = 1; fit.iterations <= 30; ++fit.iterations) {
        const Eigen::VectorXd r = residuals(p);
        Eigen::MatrixXd J(r.size(), static_cast<Eigen::Index>(names.size()));
        for (std::size_t c = 0; c < names.size(); ++c) {
            const double h = 1e-5 * std::max(1.0, std::abs(p[names[c]]));
            auto plus = p, minus = p;
            plus[names[c]] += h;
            minus[names[c]] -= h;
            J.col(Eigen::Index(c)) = (residuals(plus) - residuals(minus)) / (2 * h);
        }
        const Eigen::VectorXd step = J.colPivHouseholderQr().solve(-r);
        for (std::size_t c = 0; c < names.size(); ++c) p[names[c]] += step(Eigen::Index(c));
        if (step.norm() < 1e-10) break;
    }
    fit.values = p;
    const Eigen::VectorXd r = residuals(p);
    for (std::size_t i = 0; i < tips.size(); ++i) fit.residual = std::max(fit.residual, r.segment<3>(Eigen::Index(3 * i)).norm());
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

CompensationTerm fit_fourier(const std::vector<double>& angle, const std::vector<double>& error, int order, double& max_residual) {
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
    const Eigen::VectorXd c = A.colPivHouseholderQr().solve(b);
    CompensationTerm t;
    t.kind = CompensationTerm::Kind::Fourier;
    t.a0 = c(0);
    for (int k = 1; k <= order; ++k) {
        t.cosines.push_back(c(2 * k - 1));
        t.sines.push_back(c(2 * k));
    }
    max_residual = (A * c - b).cwiseAbs().maxCoeff();
    return t;
}

}  // namespace xlate5
