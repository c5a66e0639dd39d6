// SPDX-License-Identifier: GPL-3.0-or-later
// `--preview FILE.html`: one self-contained page to look at a translation before printing it: a
// 3D view (three.js with its OrbitControls, inlined: three_js.hpp) of the tip path coloured by
// tilt, deviation or feed, travels dashed, the tool axis on demand, the bed and the build volume,
// and the machine itself (its file's collision bodies, else a default from the chains) posed by
// forward kinematics at the written line under a scrubber; the report's pole crossings, unwinds,
// branch changes, re-zeros and collisions and the moves a joint's max_feed slows, listed and
// clickable; every joint over the file against its limits.
// Stage: an observer beside the pipeline. It reads the written output back (so it shows what the
// firmware will be told), and joins the report's marks to the written move line each ended on,
// so the page and the report count the same. May call: translators/kinematics, the machine data,
// the report, firmware_length (the written feed's length rule).
// Deviation of a written move: how far the firmware's joint-linear path leaves the straight line
// between the tips at its two ends, sampled; a thinned-out point keeps the worst of the moves it
// stands for. A move whose tip swings off that line by more than the tolerance keeps
// its sampled tips, so the swing is drawn as the firmware moves it.
// Memory is bounded whatever the file size: at most KeptMoves::kMaxPoints moves are kept, evenly spaced
// (when full, every other one is dropped and the spacing doubles); docs/limits.md.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "translators/inspect/report.hpp"
#include "translators/kinematics/kinematics.hpp"

namespace xlate5 {

// A body of the machine drawn in the preview: a shape fixed to one frame of a chain. `frame`:
// "part" or "tool" (the chain's end: the build plate, the nozzle tip) or "part:K" / "tool:K"
// (the frame after the chain's first K elements, "tool:0" the machine's base); `pose`: the
// shape's place in that frame, a 3 x 4 matrix row by row (rotation, then translation). Shapes
// are the collision check's (FCL's, centred on their frame): a box's size is its edges along
// the pose's x y z; a cylinder's, cone's or capsule's (radius, radius, length) along its z (a
// cone's apex at +length/2, a capsule's length between its sphere centres); a sphere's
// (radius, radius, radius); a mesh's vertices and triangles are in `vertices` and `triangles`.
struct PreviewBody {
    std::string name;
    std::string frame;
    enum class Shape { Box, Cylinder, Cone, Capsule, Sphere, Mesh } shape = Shape::Box;
    std::array<double, 3> size{};
    std::array<double, 12> pose{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    std::vector<double> vertices;            // mesh: x y z per vertex, in the shape's frame
    std::vector<std::uint32_t> triangles;    // mesh: three vertex indices per triangle
    std::size_t source_triangles = 0;        // mesh: triangles before thinning
};
// A simple machine from the chains alone: the bed (a table disc when the part chain turns),
// each rotary joint's axis as a cylinder, the nozzle and its holder along the tool axis.
std::vector<PreviewBody> default_bodies(const Machine& machine);
// The machine's own collision bodies ([[bodies]], the ones the check uses), each on its chain
// frame; meshes thinned by vertex clustering to kMaxPreviewTriangles together (docs/limits.md).
// Empty when the machine has none.
inline constexpr std::size_t kMaxPreviewTriangles = 20000;
std::vector<PreviewBody> machine_bodies(const Machine& machine);

// The build volume in the part frame from the linear joints whose chain axis is a coordinate
// axis (a joint's travel moves the tip along it, or the plate against it): their limits.
// Coordinates without such a joint get no extent (lo 0, hi -1: the page takes the path's).
struct BuildVolume {
    double lo[3] = {0, 0, 0}, hi[3] = {-1, -1, -1};
};
BuildVolume build_volume(const Machine& machine);

// A marked written move: one of the report's events at the written move it ended on, or the
// first of a run of moves at a joint's max_feed.
struct PreviewMark {
    enum class Kind { PoleCrossing, Unwind, BranchChange, Rezero, Slowed };
    static Kind of(DeviationReport::MarkKind kind);
    Kind kind;
    std::uint64_t move;  // written move number, from 0
    double tip[3];
};

// The written moves the preview keeps, row by row: at most kMaxPoints, evenly spaced (when
// full, every other one is dropped and the spacing `every` doubles).
struct KeptMoves {
    static constexpr std::size_t kMaxPoints = 4000;
    static constexpr std::size_t kLineText = 80;  // characters of a kept line's text shown
    std::size_t joints = 0;
    std::vector<double> q;        // joints, row by row
    std::vector<char> prints;     // 1 when the move extrudes (it has an E word)
    std::vector<double> feed;     // the feed written (modal)
    std::vector<std::uint64_t> move_no, line_no;  // written move number (from 0), output line (from 1)
    std::vector<std::string> text;  // the line's text (at most kLineText characters)
    std::vector<std::vector<double>> swing;  // sampled tips of a move that leaves its chord (else empty)
    std::vector<double> dev;      // worst tip deviation (mm) of the moves each stands for
    std::uint64_t every = 1;
    std::size_t size() const { return q.size() / joints; }
    // Full: every other kept move dropped (its deviation kept by the one after it; the last
    // one's, when dropped, added to `dev_since`, the next one's).
    void halve(double& dev_since);
};

// What the preview collected from the written output, for the page.
struct PreviewData {
    KeptMoves kept;
    std::vector<double> low, high;  // every move's joints, not only the kept ones
    std::uint64_t moves = 0;        // written move lines
    std::vector<PreviewMark> marks;  // the report's events joined to their written moves
    std::uint64_t slowed = 0, slowed_runs = 0;  // moves at a joint's max_feed, and runs of them
    std::vector<PreviewMark> slowed_marks;      // each run's first move
    std::vector<std::pair<std::uint64_t, std::uint64_t>> drains;
};

// The page (preview_page.cpp): the collected data, every mark to draw (the joined ones and
// those not joined yet, on the last move) and the machine, its bodies and the report.
std::string preview_page(const Kinematics& kinematics, const DeviationReport& report, const PreviewData& data,
                         const std::vector<PreviewMark>& marks, const std::string& title);

// The collection: reads the written output back, keeps what the page draws.
class Preview {
public:
    // A joint is at its max_feed when the written feed moves it at this share of it or more.
    static constexpr double kAtMaxFeed = 0.995;
    using Kind = PreviewMark::Kind;
    using Mark = PreviewMark;

    // `events`: the translation's report, whose marks arrive before the output lines they belong to.
    Preview(const Kinematics& kinematics, const DeviationReport& events);

    // A block of written output (whole lines); G0/G1 and G92 lines move or set the joints.
    void scan(std::string_view output);
    // The pre-flight's line ranges where the serial link lets the planner drain (first, last output
    // line), listed on the page.
    void set_drains(std::vector<std::pair<std::uint64_t, std::uint64_t>> ranges) { data_.drains = std::move(ranges); }
    // The page: `title` names the input file and machine.
    std::string html(const std::string& title) const;
    // What the written output holds that the report's own counts do not: JSON members, one a line
    // (DeviationReport::set_written).
    std::string report_json() const;
    const PreviewData& data() const { return data_; }

private:
    void line(std::string_view l);
    void keep();
    double deviation(const std::vector<double>& from, const std::vector<double>& to, bool keep_samples);
    void join_marks(std::uint64_t through);
    void check_feed();

    const Kinematics& kin_;
    const DeviationReport& events_;
    std::size_t joined_ = 0;       // the report's marks placed so far
    std::size_t joints_;
    std::vector<double> q_now_;
    std::vector<double> q_before_; // joints before the move being read
    bool printing_ = false;        // the line being read extrudes
    double f_ = 0;                 // modal feed as written
    std::uint64_t lines_ = 0;
    std::string pending_;          // a line cut by the block boundary
    std::string_view current_;     // the line being read
    double dev_since_ = 0;         // worst deviation of the moves since the last kept one
    std::vector<double> swing_now_, swing_since_;  // sampled tips of the move read, of the worst since the last kept
    double swing_dev_ = 0;
    bool slowed_last_ = false;
    PreviewData data_;
};

}  // namespace xlate5
