// SPDX-License-Identifier: GPL-3.0-or-later
// The firmware feed rules. What it may call: see feed_rules.hpp.
#include "translators/pipeline/feed_rules.hpp"

#include <algorithm>
#include <cmath>

#include "translators/number.hpp"

namespace xlate5 {

namespace {

double linear_squared(const double* q0, const double* q1, const JointKinds& kinds) {
    double lin2 = 0;
    for (const std::size_t j : kinds.linear) {
        const double d = q1[j] - q0[j];
        lin2 += d * d;
    }
    return lin2;
}

double rotary_squared(const double* q0, const double* q1, const JointKinds& kinds) {
    double rot2 = 0;
    for (const std::size_t j : kinds.rotary) {
        const double d = q1[j] - q0[j];
        rot2 += d * d;
    }
    return rot2;
}

}  // namespace

double nist_length(const double* q0, const double* q1, const JointKinds& kinds, double) {
    const double lin2 = linear_squared(q0, q1, kinds);
    return lin2 > 0 ? std::sqrt(lin2) : std::sqrt(rotary_squared(q0, q1, kinds));
}

double marlin_articulated_length(const double* q0, const double* q1, const JointKinds& kinds, double) {
    const double lin2 = linear_squared(q0, q1, kinds);
    return std::sqrt(lin2 + rotary_squared(q0, q1, kinds));
}

double klipper_length(const double* q0, const double* q1, const JointKinds& kinds, double e) {
    const double lin2 = linear_squared(q0, q1, kinds);
    if (lin2 > 0) return std::sqrt(lin2);
    double most = 0;
    for (const std::size_t j : kinds.rotary) most = std::max(most, std::abs(q1[j] - q0[j]));
    return std::max(most, e);
}

LengthRule length_rule(FirmwareDialect firmware) {
    switch (firmware) {
        case FirmwareDialect::MarlinArticulated: return marlin_articulated_length;
        case FirmwareDialect::Klipper: return klipper_length;
        case FirmwareDialect::Marlin:
        case FirmwareDialect::RepRap:
        case FirmwareDialect::Generic: break;
    }
    return nist_length;
}

namespace {

// The joints the firmware's length reads, by kind. An absent joint (core-rtheta's Y, solved
// within a micron of 0) is never written, so it is left out: counted, its last-digit flicker
// made a turn of C a 0.00001 mm linear move, written at F0.019.
JointKinds written_kinds(const Machine& m) {
    JointKinds kinds;
    for (std::size_t j = 0; j < m.joints.size(); ++j)
        if (!m.joints[j].absent) (m.joints[j].rotary ? kinds.rotary : kinds.linear).push_back(j);
    return kinds;
}

}  // namespace

double firmware_length(const Machine& m, const std::vector<double>& q0, const std::vector<double>& q1) {
    std::vector<double> a(q0.size()), b(q1.size());
    for (std::size_t j = 0; j < q0.size(); ++j) {
        a[j] = printed_value(m, j, q0[j]);
        b[j] = printed_value(m, j, q1[j]);
    }
    return length_rule(m.dialect.firmware)(a.data(), b.data(), written_kinds(m), 0);
}

// Below 1e-9 (a piece no step of which could be timed) the least feed nine decimals can write;
// else two significant digits. Written feeds of half a unit and more are as they are.
PassedNumber feed_number(double v, int decimals) {
    static constexpr double kHalfUnit[] = {0.5, 0.05, 0.005, 5e-4, 5e-5, 5e-6, 5e-7, 5e-8, 5e-9, 5e-10};
    if (!(v > 0) || decimals < 0 || decimals > 9 || v >= kHalfUnit[decimals]) [[likely]]
        return {v, {}, decimals};
    int d = decimals;
    while (d < 9 && v < 20 * kHalfUnit[d]) ++d;  // 20 half units: two significant digits
    if (v < kHalfUnit[9]) v = 1e-9;
    return {v, {}, d};
}

FeedRule::FeedRule(const Machine& machine)
    : length_(length_rule(machine.dialect.firmware)), kinds_(written_kinds(machine)), rotary_feed_(machine.motion.rotary_feed) {
    for (std::size_t j = 0; j < machine.joints.size(); ++j)
        if (!machine.joints[j].absent && machine.joints[j].max_feed > 0) limits_.push_back({j, machine.joints[j].max_feed});
}

PieceFeed FeedRule::piece(const MoveFeed& mv, std::span<const double> qprev, std::span<const double> qk, double share) const {
    PieceFeed out;
    double t = mv.minutes * share;
    // Per-axis limits slow the piece down, never change its path; a pure turn runs at the
    // machine's rotary feed.
    for (const FeedLimit& l : limits_) t = std::max(t, std::abs(qk[l.joint] - qprev[l.joint]) / l.max_feed);
    if (mv.length == 0 && mv.inverse_time == 0) {
        double rot_max = 0;
        for (const std::size_t j : kinds_.rotary) rot_max = std::max(rot_max, std::abs(qk[j] - qprev[j]));
        t = std::max(t, rot_max / rotary_feed_);
    }
    out.minutes = t;
    const double e = mv.e * share;
    const double d_fw = length_(qprev.data(), qk.data(), kinds_, e);  // both ends as printed
    if (mv.inverse_time_out) {
        // RepRapFirmware's G93: F is 1 / the piece's duration in minutes. An E-only piece takes
        // its extrusion at the programmed feed.
        if (t <= 0 && mv.e > 0 && mv.feed > 0) t = e / mv.feed;
        if (t <= 0 && mv.feed > 0) t = d_fw / mv.feed;
        if (t > 0) out.f = feed_number(1.0 / t, 4);
    } else if (t > 0 && d_fw > 0) {
        out.f = feed_number(d_fw / t, 1);
    } else if (mv.f && mv.inverse_time == 0) {
        out.f = mv.f;  // nothing moves (E only): F as written
    } else if (mv.feed > 0) {
        out.f = feed_number(mv.feed, 1);
    }
    return out;
}

}  // namespace xlate5
