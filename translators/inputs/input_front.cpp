// SPDX-License-Identifier: GPL-3.0-or-later
// The input front: G-code, CL data or waypoints -> the front door.
// What it may call: see input_front.hpp.
#include "translators/inputs/input_front.hpp"

#include "translators/error.hpp"
#include "translators/pipeline/translator.hpp"

namespace xlate5 {

std::optional<InputFormat> parse_input_format(std::string_view name) {
    if (name == "auto") return InputFormat::Auto;
    if (name == "gcode") return InputFormat::GCode;
    if (name == "apt" || name == "cls") return InputFormat::Apt;
    if (name == "waypoints") return InputFormat::Waypoints;
    return std::nullopt;
}

InputFront::InputFront(Translator& translator, FrontOptions options)
    : translator_(translator), o_(std::move(options)), format_(o_.format) {
    if (format_ == InputFormat::Apt) apt_ = std::make_unique<AptReader>(AptOptions{o_.input_name, o_.extrusion_per_mm, o_.chord_tolerance, o_.extrusion_decimals});
    if (format_ == InputFormat::Waypoints)
        waypoints_ = std::make_unique<WaypointReader>(WaypointOptions{o_.input_name, o_.extrusion_per_mm, o_.waypoint_feed});
}

InputFront::~InputFront() = default;

void InputFront::pass(std::string& out) {
    for (const FrontLine& l : lines_) {
        try {
            translator_.feed(l.text, l.line_no, out);
        } catch (const InputError& e) {
            // The column was one of the G-code's; the place to look is the record.
            throw InputError(e.file(), e.line(), 1, e.message() + " (the record as G-code: '" + l.text + "')");
        }
    }
    lines_.clear();
}

void InputFront::feed(std::string_view line, std::uint64_t line_no, std::string& out) {
    // A UTF-8 byte-order mark (what Windows editors put first) is no part of the first line.
    if (line_no == 1 && line.size() >= 3 && line.substr(0, 3) == "\xEF\xBB\xBF") [[unlikely]]
        line.remove_prefix(3);
    // G-code first, and as the call it ends with: most lines take only this test.
    if (format_ == InputFormat::GCode) return translator_.feed(line, line_no, out);
    feed_other(line, line_no, out);
}

void InputFront::feed_other(std::string_view line, std::uint64_t line_no, std::string& out) {
    if (format_ == InputFormat::Auto) {
        bool empty = true;
        for (char c : line)
            if (c != ' ' && c != '\t' && c != '\r') empty = false;
        if (empty) {
            translator_.feed(line, line_no, out);
            return;
        }
        format_ = looks_like_apt(line) ? InputFormat::Apt : InputFormat::GCode;
        if (format_ == InputFormat::GCode && o_.extrusion_per_mm > 0)
            throw InputError(o_.input_name, line_no, 1, "this is G-code, which has its own E: the extrusion rate per mm is for CL data and waypoint tables");
        if (format_ == InputFormat::Apt) apt_ = std::make_unique<AptReader>(AptOptions{o_.input_name, o_.extrusion_per_mm, o_.chord_tolerance, o_.extrusion_decimals});
    }
    switch (format_) {
        case InputFormat::GCode: translator_.feed(line, line_no, out); return;
        case InputFormat::Apt: apt_->read(line, line_no, lines_); break;
        case InputFormat::Waypoints: waypoints_->read(line, line_no, lines_); break;
        case InputFormat::Auto: break;
    }
    pass(out);
}

void InputFront::finish(std::uint64_t last_line, std::string& out) {
    if (apt_) apt_->finish(last_line, lines_);
    pass(out);
    translator_.finish(out);
}

}  // namespace xlate5
