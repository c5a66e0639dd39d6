// SPDX-License-Identifier: GPL-3.0-or-later
// The kinematic-error report and the log that holds measured moves for it. What it may call: see report.hpp.
#include "translators/inspect/report.hpp"

#include "translators/machine/machine.hpp"
#include "translators/pipeline/motion.hpp"

#include <cmath>

namespace xlate5 {

DeviationReport::DeviationReport(std::string file, std::string machine, double tolerance, double angle_tolerance)
    : file_(std::move(file)), machine_(std::move(machine)), tolerance_(tolerance), angle_tolerance_(angle_tolerance) {}

void MoveLog::add(std::uint64_t line, const MoveResult& m) {
    bool half_turn = false, printing_turn = false;
    for (std::size_t j = 0; j < m.travel.size(); ++j) {
        if (!machine_.joints[j].rotary) continue;
        half_turn = half_turn || m.travel[j] >= EventLog::kHalfTurnDeg;
        printing_turn = printing_turn || (m.prints && m.travel[j] > EventLog::kPrintingTurnDeg);
        if (hold_) held_.travel.emplace_back(machine_.joints[j].name, m.travel[j]);
        else report_.joints.add_travel(machine_.joints[j].name, m.travel[j]);
    }
    const std::size_t n = machine_.joints.size();
    const bool ranged = m.low.size() == n && m.high.size() == n;
    if (hold_) {
        held_.moves.push_back({line, m.tip_error, m.angle_error, m.feed_error, m.pieces, held_.travel.size(), m.minutes, int(m.change), m.pole_crossings, half_turn,
                               m.rezeros, printing_turn, m.moves_written, true});
        for (std::size_t j = 0; j < n; ++j) held_.ranges.push_back(ranged ? m.low[j] : NAN);
        for (std::size_t j = 0; j < n; ++j) held_.ranges.push_back(ranged ? m.high[j] : NAN);
        return;
    }
    report_.add_move(line, m.tip_error, m.angle_error, m.feed_error, m.pieces);
    ranges_.clear();
    for (std::size_t j = 0; j < n; ++j) ranges_.push_back(ranged ? m.low[j] : NAN);
    for (std::size_t j = 0; j < n; ++j) ranges_.push_back(ranged ? m.high[j] : NAN);
    add_rest(ranges_.data(), m.minutes, int(m.change));
    report_.events.add_route(m.pole_crossings, half_turn, printing_turn);
    report_.events.add_marks(line, m.moves_written, m.pole_crossings, int(m.change), m.rezeros);
}

void MoveLog::add_rezeros(std::uint64_t line, std::uint64_t moves_written, int rezeros) {
    if (!hold_) {
        report_.events.add_marks(line, moves_written, 0, int(SolutionChange::None), rezeros);
        return;
    }
    held_.moves.push_back({line, 0, 0, 0, 0, held_.travel.size(), 0, int(SolutionChange::None), 0, false, rezeros, false, moves_written, false});
    held_.ranges.insert(held_.ranges.end(), 2 * machine_.joints.size(), NAN);
}

void MoveLog::drop_held_from(std::size_t moves) {
    if (moves >= held_.moves.size()) return;
    held_.travel.resize(moves == 0 ? 0 : held_.moves[moves - 1].travel_end);
    held_.ranges.resize(moves * 2 * machine_.joints.size());
    held_.moves.resize(moves);
}

void MoveLog::add_rest(const double* ranges, double minutes, int change) {
    const std::size_t n = machine_.joints.size();
    for (std::size_t j = 0; j < n; ++j)
        if (!std::isnan(ranges[j])) report_.joints.add_range(machine_.joints[j].name, ranges[j], ranges[n + j]);
    report_.stats.minutes += minutes;
    report_.events.add_solution_change(change == int(SolutionChange::Turns), change == int(SolutionChange::Branch));
}

void MoveLog::release(std::size_t moves) {
    if (moves == 0) return;
    const std::size_t travel_end = held_.moves[moves - 1].travel_end;
    const std::size_t n = machine_.joints.size();
    for (std::size_t i = 0, t = 0; i < moves; ++i) {
        const Pending& m = held_.moves[i];
        if (m.measured) {
            report_.add_move(m.line, m.tip, m.angle, m.feed, m.pieces);
            report_.events.add_route(m.pole_crossings, m.half_turn, m.printing_turn);
            add_rest(&held_.ranges[i * 2 * n], m.minutes, m.change);
        }
        report_.events.add_marks(m.line, m.moves_written, m.pole_crossings, m.change, m.rezeros);
        for (; t < m.travel_end; ++t) report_.joints.add_travel(held_.travel[t].first, held_.travel[t].second);
    }
    held_.ranges.erase(held_.ranges.begin(), held_.ranges.begin() + std::ptrdiff_t(moves * 2 * n));
    held_.moves.erase(held_.moves.begin(), held_.moves.begin() + std::ptrdiff_t(moves));
    held_.travel.erase(held_.travel.begin(), held_.travel.begin() + std::ptrdiff_t(travel_end));
    for (Pending& m : held_.moves) m.travel_end -= travel_end;
}

}  // namespace xlate5
