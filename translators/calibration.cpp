#include "translators/calibration.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "translators/error.hpp"

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
    f.rho = std::atan2(n.x(), n.z()) * 180.0 / 3.14159265358979323846;
    f.psi = std::atan2(-n.y(), std::hypot(n.x(), n.z())) * 180.0 / 3.14159265358979323846;
    for (const auto& p : points) f.residual = std::max(f.residual, std::abs((p - centroid).dot(n)));
    return f;
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

}  // namespace xlate5
