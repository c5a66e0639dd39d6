// SPDX-License-Identifier: GPL-3.0-or-later
// The compensation stage's tables: measured errors by rotary angle.
// What it may call: see compensation.hpp.
#include "translators/pipeline/compensation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "translators/constants.hpp"

namespace xlate5 {

bool CompensationTerm::eval(double x, double& e) const {
    if (kind == Kind::Fourier) {
        e = a0;
        for (std::size_t k = 0; k < cosines.size(); ++k) e += cosines[k] * std::cos(double(k + 1) * x * kRadPerDeg);
        for (std::size_t k = 0; k < sines.size(); ++k) e += sines[k] * std::sin(double(k + 1) * x * kRadPerDeg);
        return true;
    }
    const std::size_t n = angle.size();
    if (periodic) {
        // Wrap into [first, first + 360) and interpolate across the seam between last and first.
        double w = std::fmod(x - angle.front(), 360.0);
        if (w < 0) w += 360.0;
        w += angle.front();
        for (std::size_t i = 0; i + 1 < n; ++i)
            if (w >= angle[i] && w <= angle[i + 1]) {
                const double t = (w - angle[i]) / (angle[i + 1] - angle[i]);
                e = error[i] + t * (error[i + 1] - error[i]);
                return true;
            }
        const double span = angle.front() + 360.0 - angle.back();
        const double t = (w - angle.back()) / span;
        e = error.back() + t * (error.front() - error.back());
        return true;
    }
    if (x < angle.front() || x > angle.back()) {
        if (!clamp) return false;
        e = x < angle.front() ? error.front() : error.back();
        return true;
    }
    const auto it = std::upper_bound(angle.begin(), angle.end(), x);
    const std::size_t i = it == angle.end() ? n - 2 : std::size_t(it - angle.begin()) - 1;
    const double t = (x - angle[i]) / (angle[i + 1] - angle[i]);
    e = error[i] + t * (error[i + 1] - error[i]);
    return true;
}

std::string Compensation::apply(std::vector<double>& q) const {
    for (const auto& t : terms) {
        double e = 0;
        if (!t.eval(q[std::size_t(t.by)], e)) {
            char buf[200];
            std::snprintf(buf, sizeof buf, "the compensation table (%s) covers %.3f .. %.3f degrees, not %.3f", source.c_str(),
                          t.angle.front(), t.angle.back(), q[std::size_t(t.by)]);
            return buf;
        }
        q[std::size_t(t.joint)] -= e;
    }
    return {};
}

void Compensation::undo(std::vector<double>& q) const {
    for (const auto& t : terms) {
        double e = 0;
        if (t.eval(q[std::size_t(t.by)], e)) q[std::size_t(t.joint)] += e;
    }
}

}  // namespace xlate5
