// SPDX-License-Identifier: GPL-3.0-or-later
// The collision stage's clearance cache: each tool body's cleared distances to the beads and the
// other bodies, the bodies' odometers and the epoch they count in. Builds on collide_bounds.hpp.
#pragma once
#include <cstdint>
#include <vector>

#include "translators/pipeline/collide_bounds.hpp"

namespace xlate5::collision_parts {

struct CollideClearance : CollideBounds {
    explicit CollideClearance(const Machine& m) : CollideBounds(m) {
        solid_clear.resize(tools.size() * solids.size());
        new_epoch();
    }

    // Cached clearance (conservative advancement carried across steps and pieces): a distance d
    // measured between a tool body and a bead (or obstacle) stays a lower bound until the pair
    // has moved d towards each other. Each solid's odometer sums its motion bound (step_rate)
    // over the steps swept clear in a row; a pair is skipped while its odometers at the step's
    // end are below what they were when measured plus d. A sweep that does not start where the
    // last one ended clear (a contact, a detour's retry, the look-back's replay) starts a new
    // epoch: every cached value lapses.
    struct Clear {
        double until = 0;          // the pair's odometer sum up to which it cannot meet
        std::uint32_t epoch = 0;   // 0: never measured
    };
    std::vector<Clear> bead_clear;      // per bead and tool (beads.size() x tools.size())
    std::vector<Clear> solid_clear;     // per tool and solid (tools.size() x solids.size())
    std::vector<double> odo;            // per solid: motion bound summed, this epoch
    std::uint32_t epoch = 1;
    void new_epoch() {
        ++epoch;
        odo.assign(solids.size(), 0.0);
    }
    // Whether the pair (tool k, with odometer sum `at_start` at the step's start and `moving`
    // over it) is known apart over the whole step.
    bool known_clear(const Clear& c, double at_start, double moving) const {
        return c.epoch == epoch && at_start + moving < c.until;
    }
};

}  // namespace xlate5::collision_parts
