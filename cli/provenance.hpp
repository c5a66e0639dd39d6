// SPDX-License-Identifier: GPL-3.0-or-later
// What a file says of where it comes from (stage: command line; calls nothing of the pipeline):
// the header line every output of xlate5 starts with, and the checks that keep a slicer's
// post-processing from translating a file twice or a binary file at all.
//
// `; xlate5 VERSION machine=NAME joint space` (a translation) or `... tool space` (--inverse).
// A file that starts with the header of what the command would write (joint space into a
// translation, tool space into --inverse) has been translated already: translating it again
// moves every point by the machine's kinematics once more. It is refused unless forced.
#pragma once
#include <optional>
#include <string>
#include <string_view>

namespace xlate5::cli {

enum class Space { Joint, Tool };

// "; xlate5 0.1.0 machine=rw2 joint space" (no newline).
std::string provenance_header(std::string_view version, std::string_view machine, Space space);

// The space a header line names, or nullopt when the line is not an xlate5 header.
std::optional<Space> read_provenance(std::string_view line);

// True when the first bytes are the magic of binary G-code (PrusaSlicer's .bgcode: "GCDE").
bool is_binary_gcode(std::string_view first_line);

// The message for a binary G-code input: what to change in the slicer.
std::string binary_gcode_message();

}  // namespace xlate5::cli
