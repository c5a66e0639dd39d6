// SPDX-License-Identifier: GPL-3.0-or-later
// Error compensation (Andersons, Twente 2023, eq. 4.6): measured deviations of the tip as functions
// of a rotary angle, subtracted from the joint targets after IK and added back by --inverse.
// The compensation stage sits between the motion stage (and the planner's joint moves and G92s,
// which translator.cpp hands it) and the emitter: nominal joints in, the joints the firmware is sent out, or why not. May call: nothing
// but its own tables. (The series `calibrate fit` prints is fitted in calibration.hpp.)
#pragma once
#include <span>
#include <string>
#include <vector>

namespace xlate5 {

struct CompensationTerm {
    int joint = -1;  // the joint corrected (index into Machine::joints)
    int by = -1;     // the rotary joint whose angle the error depends on
    enum class Kind { Table, Fourier } kind = Kind::Table;
    // Table: measured (angle, error) points, angles ascending; linear between them, or periodic
    // (wrapping at 360 degrees, so the last point joins the first).
    std::vector<double> angle, error;
    bool periodic = false;
    bool clamp = false;  // outside the table: the end value (false: refuse the move)
    // Fourier: error = a0 + sum_k cos[k-1] cos(k angle) + sin[k-1] sin(k angle).
    double a0 = 0;
    std::vector<double> cosines, sines;

    // The error at `angle` (degrees); false where the table refuses to extrapolate.
    bool eval(double angle, double& e) const;
};

struct Compensation {
    std::vector<CompensationTerm> terms;
    std::string source;  // where it was read from, for messages
    bool empty() const { return terms.empty(); }
    // Nominal joints -> what the firmware is sent. Returns an empty string, or why not.
    std::string apply(std::vector<double>& q) const;
    // Sent joints -> nominal (exact: no corrected joint is an input of a term).
    void undo(std::vector<double>& q) const;
};

// The stage: holds its scratch so a move allocates nothing. Copyable (a pointer to the terms).
class CompensationStage {
public:
    explicit CompensationStage(const Compensation& compensation) : compensation_(&compensation) {}

    struct Result {
        std::span<const double> sent;          // q itself when there is nothing to correct
        const std::string* failure = nullptr;  // the stage's text of why the joints cannot be corrected, or none
        bool ok() const { return failure == nullptr; }
        const std::string& why() const { return *failure; }
    };
    // Nominal joints -> what the firmware is sent (valid until the next call). The usual answer
    // (nothing to correct, or corrected) builds no text: a move asks with every piece.
    Result apply(std::span<const double> q) {
        if (compensation_->empty()) return {q};
        sent_.assign(q.begin(), q.end());
        why_ = compensation_->apply(sent_);
        return {sent_, why_.empty() ? nullptr : &why_};
    }

private:
    const Compensation* compensation_;
    std::vector<double> sent_;
    std::string why_;
};

}  // namespace xlate5
