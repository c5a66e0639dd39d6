// SPDX-License-Identifier: GPL-3.0-or-later
// The collision stage: every move piece the emitter is about to write is checked, over its
// joint-linear sweep, for the machine's tool-side bodies meeting the part printed so far, the
// part-side bodies (bed, table, fixtures) or the bodies fixed to the base; every extruding piece
// then adds its bead to the printed part. On FCL (broad phase: a dynamic AABB tree of the beads).
// It watches the emitter (PieceObserver) and keeps its place in the printed part in the line's
// state (CollideCursor), so a line refused or translated again by the look-back lays its beads
// once. Derivation of the sweep's bound: docs/machines.md, "Bodies". May call: kinematics data
// of the machine (its chains), FCL.
#pragma once
#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/emitter.hpp"
#include "translators/pipeline/modes.hpp"

namespace xlate5 {

// Part of the stages' state (StageState, lookback.hpp): how many beads the printed part holds, the extruder's
// absolute position as last written, and the input line being translated.
struct CollideCursor {
    std::uint64_t beads = 0;
    double e = 0;
    double retracted = 0;  // filament drawn back and not yet pushed out again (mm of E)
    std::uint64_t line = 0;
};

enum class CollisionPolicy { Refuse, Warn, Off };

struct CollisionEvent {
    std::uint64_t line = 0;      // the input line whose move collides
    std::string tool_body;
    std::string other;           // a body's name, or "printed part"
    std::uint64_t bead_line = 0; // the printed part: the line that printed the bead met
    Eigen::Vector3d at = Eigen::Vector3d::Zero();  // part frame, mm
    std::uint64_t moves_written = 0;  // move lines written before the piece (set by the translator: the preview's place)
    // A travel re-routed round the contact (lifted `lift` mm along the tool axis), not refused.
    bool rerouted = false;
    double lift = 0;
    // "collision: <tool body> meets <printed part at line N | body> at X Y Z"; re-routed:
    // "travel re-routed, lifted L mm: <tool body> would meet <...> at X Y Z"
    std::string message() const;
};

// The printed part's bound (docs/limits.md): beads held at once. Past it the line is refused.
inline constexpr std::size_t kMaxBeads = 2'000'000;

class CollisionStage final : public PieceObserver {
public:
    // The machine (kinematics.machine()) must have geometry. `cursor` and `modes` are the live
    // line state's. `reroute` and `lift` override the machine file's [collision] settings.
    CollisionStage(const Kinematics& kinematics, CollisionPolicy policy, CollideCursor& cursor, const Modes& modes,
                   std::optional<bool> reroute = std::nullopt, std::optional<double> lift = std::nullopt);
    ~CollisionStage();
    CollisionStage(const CollisionStage&) = delete;
    CollisionStage& operator=(const CollisionStage&) = delete;

    const std::vector<std::vector<double>>* piece(std::span<const double> from, std::span<const double> to,
                                                  const std::optional<PassedNumber>& e) override;
    // A detour for the travel q0 -> q1 round what it meets: lifted along the tool axis at q0, across,
    // lowered onto q1, each leg swept clear; the two lifted ends, or none.
    std::optional<std::vector<std::vector<double>>> reroute(std::span<const double> q0, std::span<const double> q1, double& lift);
    void e_set(double e) override { cursor_.e = e; }

    // The first contact of a tool body over the joint-linear sweep from q0 to q1, if any.
    std::optional<CollisionEvent> sweep(std::span<const double> q0, std::span<const double> q1);
    // The contacts at one pose (xlate5 pose): every tool body against every obstacle.
    std::vector<CollisionEvent> touching(std::span<const double> q);
    // The least distance (mm) between a tool body and an obstacle or bead at joints q, every
    // pair measured (no broad phase): the reference the tests hold the sweep against.
    double clearance(std::span<const double> q);
    // Adds the bead from the tip at q0 to the tip at q1, `e` mm of filament (<= 0: the default width).
    void add_bead(std::span<const double> q0, std::span<const double> q1, double e, std::uint64_t line);
    std::size_t beads() const;

    // Told of every collision found (warn and refuse) and every travel re-routed (`rerouted`).
    std::function<void(const CollisionEvent&)> on_collision;
    std::uint64_t distance_queries() const;  // for the benchmark

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    CollideCursor& cursor_;
    const Modes& modes_;
    CollisionPolicy policy_;
    const Kinematics& kinematics_;
    bool reroute_;
    double lift_;
    std::vector<std::vector<double>> detour_;
};

}  // namespace xlate5
