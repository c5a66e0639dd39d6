// SPDX-License-Identifier: GPL-3.0-or-later
// A machine is data: two kinematic chains, joints with limits, and the firmware dialect.
// Loaded from a TOML file (machine_file.cpp); all the math on it lives in kinematics.cpp.
// No stage: every stage reads it. machine_file.cpp may call: expr, the compensation tables.
#pragma once
#include <Eigen/Geometry>

#include "translators/machine/geometry.hpp"
#include "translators/pipeline/compensation.hpp"
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace xlate5 {

// How tool orientation is read from the input (ISO/Fanuc switch codes).
enum class OrientationMode {
    Angles,  // G43.4: tool-centre-point control, the machine's rotary letters give orientation
    Vector,  // G43.5: tool-centre-point control, I J K give the tool axis
    Joints,  // G49:   off; every word is a joint value sent to the firmware as is
};

struct Joint {
    char name = 0;           // letter in the input (tool space and G49 joint space)
    char output = 0;         // letter the firmware knows the joint by
    bool rotary = false;     // degrees; otherwise mm
    double min = -1e300;     // limits, in the joint's unit; rotaries without limits are unbounded
    double max = 1e300;
    double home = 0;         // joint value after G28
    double max_feed = 0;     // mm/min or deg/min the axis can move at; 0: no limit known
    double rezero_beyond = 0;  // unbounded rotary: past +-this many degrees, re-zero with G92 on a travel move (0: never)
    // Klipper: the [manual_stepper NAME] that drives this joint (an extra axis); the loader
    // gives "axis_" and the lower-case output letter when the file names none.
    std::string manual_stepper;
    // The machine has no such axis (a polar printer's Y): a linear joint held at `home`, its
    // limits home +- kAbsentSlack, never written to the firmware.
    bool absent = false;
    bool bounded() const { return min > -1e299 || max < 1e299; }
};

struct ChainElement {
    enum class Kind { Fixed, Linear, Rotary } kind = Kind::Fixed;
    int joint = -1;                       // Linear/Rotary: index into Machine::joints
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // Linear: direction; Rotary: rotation axis (unit)
    Eigen::Vector3d point = Eigen::Vector3d::Zero();  // Rotary: a point on the axis
    Eigen::Isometry3d fixed = Eigen::Isometry3d::Identity();  // Fixed
};

// How the firmware measures a move's length for F (the motion stage uses it) and how it is fed.
enum class FirmwareDialect { Marlin, MarlinArticulated, RepRap, Klipper, Generic };

struct Dialect {
    FirmwareDialect firmware = FirmwareDialect::Marlin;
    int linear_decimals = 3;
    int rotary_decimals = 3;
    int extrusion_decimals = 5;   // E of the pieces a move is split into
    bool inverse_time = false;    // write G93 inverse-time feeds (RepRapFirmware supports them)
};

// The firmware's planner, for the pre-flight estimate (inspect/preflight): Marlin 2.1's stock
// Configuration.h values unless the machine file's [firmware] says otherwise.
struct PlannerSettings {
    double acceleration = 3000;        // mm/s^2 (deg/s^2 for a rotary-only move): DEFAULT_ACCELERATION
    double junction_deviation = 0.013; // mm: JUNCTION_DEVIATION_MM
    double min_segment_time = 0.02;    // s: MIN_SEGMENT_TIME (20000 us)
    int blocks = 16;                   // BLOCK_BUFFER_SIZE: the planner's horizon
};

// How moves are split and fed (the motion stage).
struct MotionSettings {
    double tolerance = 0.01;       // mm: the tip may leave the programmed line by at most this
    double angle_tolerance = 0.5;  // degrees: the tool axis may leave its great-circle path by this
    double rotary_feed = 3600;     // deg/min for a pure reorientation (no tip motion)
    bool segment = true;           // split moves to the tolerance (off: one joint move per input move)
    // Output moves one input line may become; not a machine-file key. 0: the bound of
    // docs/limits.md (kMaxPiecesPerLine), which a program may only lower (the fuzz harness does,
    // to bound the work per input while still reaching the refusal).
    int max_pieces = 0;
};

struct Machine {
    std::string name;
    std::string description;
    std::string source_path;                     // the TOML file it came from
    std::map<std::string, double> parameters;    // named values after overrides
    std::vector<Joint> joints;
    std::vector<ChainElement> part_chain;        // base -> build plate (part frame)
    std::vector<ChainElement> tool_chain;        // base -> nozzle tip
    Eigen::Vector3d tool_axis = Eigen::Vector3d::UnitZ();  // tool axis in the tip frame
    OrientationMode start_mode = OrientationMode::Angles;
    Dialect dialect;
    PlannerSettings planner;
    MotionSettings motion;
    Compensation compensation;   // measured errors, subtracted from every emitted move
    // Its solid parts for the collision check ([[bodies]], geometry.hpp); null: none given.
    std::shared_ptr<const MachineGeometry> geometry;

    int joint_index(char name) const {
        for (std::size_t i = 0; i < joints.size(); ++i)
            if (joints[i].name == name) return int(i);
        return -1;
    }
    std::vector<double> home_joints() const {
        std::vector<double> q;
        for (const auto& j : joints) q.push_back(j.home);
        return q;
    }
};

// The largest machine file or compensation file read (docs/limits.md): the bundled machine files
// are under 3 KiB, and a compensation table of thousands of measured points is under 100 KiB; a
// longer file is refused before it is parsed, so a reload cannot grow the service's memory.
inline constexpr std::size_t kMaxMachineFileBytes = 1u << 20;

// Loads a machine by bundled name or by path; `overrides` replace [parameters] values
// (name -> value) before anything is computed. Throws MachineError naming file, line and key.
Machine load_machine(const std::string& name_or_path, const std::map<std::string, double>& overrides = {});
Machine load_machine_text(const std::string& toml_text, const std::string& source_name,
                          const std::map<std::string, double>& overrides = {});

// A machine file parsed once and built many times with different [parameters] values: a fit
// (`calibrate pivots`) builds the machine for every trial value, and parsing the text each time
// was most of its cost. Throws MachineError as load_machine_text does.
struct ParsedMachineFile;
class MachineTemplate {
public:
    MachineTemplate(const std::string& toml_text, const std::string& source_name);
    Machine build(const std::map<std::string, double>& overrides) const;

private:
    std::shared_ptr<const ParsedMachineFile> parsed_;
    std::string source_;
};

// Reads a compensation file ([[compensation]] terms, as in a machine file) for `machine`,
// replacing the machine's own. Throws MachineError naming the file, line and key.
void load_compensation_file(const std::string& path, Machine& machine);

// The text of a machine or compensation file, at most kMaxMachineFileBytes. Throws MachineError
// ("cannot open <what>", or the place past the bound).
std::string read_machine_file(const std::string& path, const std::string& what = "machine file");

// Where machine names are looked up, first match first: $XLATE5_MACHINES, $XDG_CONFIG_HOME/xlate5/machines
// (~/.config/xlate5/machines), /etc/xlate5/machines, then the shipped ones (../share/xlate5/machines
// from the executable's directory, then the install prefix's).
std::vector<std::string> machine_search_path();
// Every bundled machine file found on the search path, by name.
std::map<std::string, std::string> bundled_machines();

}  // namespace xlate5
