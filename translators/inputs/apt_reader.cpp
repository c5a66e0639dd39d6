// SPDX-License-Identifier: GPL-3.0-or-later
// The APT / NX CLSF front end: CL records -> canonical G43.5 G-code lines.
// What it may call: see apt_reader.hpp.
#include "translators/inputs/apt_reader.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <vector>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/inputs/gcode_lexer.hpp"

namespace xlate5 {

namespace {

// One field of a record: its text (trimmed) and where it starts in the line.
struct Field {
    std::string_view text;
    std::uint32_t column;
};

bool blank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

std::string upper(std::string_view s) {
    std::string u(s);
    for (char& c : u)
        if (c >= 'a' && c <= 'z') c = char(c - 'a' + 'A');
    return u;
}

Field trim(std::string_view s, std::uint32_t column) {
    std::size_t a = 0, b = s.size();
    while (a < b && blank(s[a])) ++a;
    while (b > a && blank(s[b - 1])) --b;
    return {s.substr(a, b - a), std::uint32_t(column + a)};
}

// Every CL coordinate, axis component, radius and feed goes through here: finite and within
// the same bound the G-code lexer puts on numbers (kMaxNumber), or an error at its column.
std::optional<double> to_number(std::string_view t) {
    if (!t.empty() && t.front() == '+') t.remove_prefix(1);
    double v = 0;
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size() || t.empty()) return std::nullopt;
    return v;
}

// NX's "Information listing" (the CLSF listed to a file) opens with a rule of '=', four lines
// "Information listing created by : user", "Date : ...", "Current work part : path", "Node name :
// host", and a second rule: the listing's, not the tool path's.
bool listing_rule(std::string_view t) {
    return t.size() >= 3 && t.find_first_not_of('=') == std::string_view::npos;
}

bool listing_header(std::string_view t) {
    const std::string u = upper(t);
    const std::size_t colon = u.find(':');
    if (colon == std::string::npos) return false;
    const std::string key = std::string(trim(std::string_view(u).substr(0, colon), 1).text);
    return key == "INFORMATION LISTING CREATED BY" || key == "DATE" || key == "CURRENT WORK PART" || key == "NODE NAME";
}

}  // namespace

bool looks_like_apt(std::string_view line) {
    const Field f = trim(line, 1);
    if (listing_rule(f.text)) return true;  // not G-code either: '=' is refused there
    const std::string u = upper(f.text);
    if (u.rfind("INFORMATION LISTING CREATED BY", 0) == 0) return true;
    for (const char* w : {"TOOL PATH/", "GOTO/", "$$", "UNITS/", "MULTAX", "LOAD/", "FEDRAT/", "RAPID", "TLDATA/", "MSYS/", "PAINT/", "PARTNO"})
        if (u.rfind(w, 0) == 0) return true;
    return false;
}

AptReader::AptReader(AptOptions options) : o_(std::move(options)) {}

void AptReader::read(std::string_view line, std::uint64_t line_no, FrontLines& out) {
    // A failed record changes nothing: the reader works on a copy of its state.
    State s = s_;
    const std::size_t out_start = out.size();
    try {
        std::string_view text = line;
        // A '$' at the end of a record (not "$$") continues it on the next line (APT).
        const Field whole = trim(text, 1);
        const bool continues = !whole.text.empty() && whole.text.back() == '$' && whole.text.rfind("$$", 0) != 0 &&
                               (whole.text.size() < 2 || whole.text[whole.text.size() - 2] != '$');
        if (continues) {
            if (s.continued.empty()) s.continued_line = line_no;
            s.continued.append(whole.text.substr(0, whole.text.size() - 1));
            s_ = std::move(s);
            return;
        }
        if (!s.continued.empty()) {
            const std::string joined = s.continued + std::string(whole.text);
            const std::uint64_t first = s.continued_line;
            s.continued.clear();
            record(joined, first, s, out);
        } else {
            record(text, line_no, s, out);
        }
    } catch (...) {
        out.resize(out_start);
        throw;
    }
    s_ = std::move(s);
}

void AptReader::finish(std::uint64_t last_line, FrontLines& out) {
    if (!s_.continued.empty())
        throw InputError(o_.input_name, s_.continued_line, 1, "the record continued with '$' has no next line");
    if (s_.circle)
        throw InputError(o_.input_name, s_.circle->line_no, 1, "CIRCLE is not followed by the GOTO that ends its arc");
    if (s_.in_path)
        throw InputError(o_.input_name, last_line, 1, "the file ends inside a TOOL PATH (no END-OF-PATH)");
    if (!s_.unit) set_unit(1.0, s_, out);  // never declared: millimetres
}

void AptReader::emit(State& s, FrontLines& out, std::uint64_t line_no, std::string text) const {
    if (!s.started) {
        // Vector form; absolute; relative E, so each move's E is its own share.
        s.started = true;
        out.push_back({line_no, "G43.5"});
        out.push_back({line_no, "G90"});
        if (o_.extrusion_per_mm > 0) out.push_back({line_no, "M83"});
    }
    if (!s.unit) {
        if (s.held.size() >= kAptHeldRecords) set_unit(1.0, s, out);
        else {
            s.held.push_back({line_no, std::move(text)});
            return;
        }
    }
    out.push_back({line_no, std::move(text)});
}

void AptReader::set_unit(double mm, State& s, FrontLines& out) const {
    s.unit = mm;
    const std::uint64_t at = s.held.empty() ? (out.empty() ? 0 : out.back().line_no) : s.held.front().line_no;
    out.push_back({at, mm == 1.0 ? "G21" : "G20"});
    for (auto& h : s.held) out.push_back(std::move(h));
    s.held.clear();
}

void AptReader::go_to(const Eigen::Vector3d& tip, const Eigen::Vector3d& axis, std::uint64_t line_no, State& s,
                      FrontLines& out) const {
    std::string g = s.rapid ? "G0" : "G1";
    for (int i = 0; i < 3; ++i) append_word(g, char('X' + i), tip[i], 6);
    for (int i = 0; i < 3; ++i) append_word(g, char('I' + i), axis[i], 9);
    if (!s.rapid) {
        // E is written in the file's unit, as the interpreter reads it (G20: inches of filament
        // per inch is the same number per millimetre). In millimetres at the firmware's decimals,
        // each move's rounding carried on to the next, so the total is the path's within half a
        // unit of the last decimal; in inches (or before the unit is known) with 12 decimals,
        // which the interpreter rounds the same way after converting.
        if (o_.extrusion_per_mm > 0 && s.tip_known) {
            const double e = (tip - s.tip).norm() * o_.extrusion_per_mm;
            if (s.unit && *s.unit == 1.0) {
                const double scale = std::pow(10.0, o_.extrusion_decimals), want = e + s.e_carry;
                const double written = std::round(want * scale) / scale;
                s.e_carry = want - written;
                append_word(g, 'E', written, o_.extrusion_decimals);
            } else {
                append_word(g, 'E', e, 12);
            }
        }
        if (!s.feed_written) append_word(g, 'F', *s.feed, 4), s.feed_written = true;
    }
    emit(s, out, line_no, std::move(g));
    s.tip = tip;
    s.axis = axis;
    s.tip_known = true;
}

// One record: its major word and the fields after '/', split at commas, with the errors at their
// columns.
struct AptReader::Record {
    const std::string& input_name;
    std::uint64_t line_no;
    Field all, major;
    std::string word;
    std::vector<Field> args;
    std::size_t slash;
    std::uint32_t end_column;  // just past the record, for a missing field

    [[noreturn]] void fail(std::uint32_t column, const std::string& why) const { throw InputError(input_name, line_no, column, why); }
    double number(const Field& f) const {
        const auto v = to_number(f.text);
        if (!v) fail(f.column, std::string("'").append(f.text).append("' is not a number"));
        if (!std::isfinite(*v) || std::abs(*v) > kMaxNumber) fail(f.column, "number beyond +-1e9");
        return *v;
    }
    std::vector<double> numbers(std::size_t from, std::size_t count) const {
        std::vector<double> v;
        for (std::size_t i = from; i < from + count; ++i) v.push_back(number(args[i]));
        return v;
    }
};

void AptReader::goto_record(const Record& r, State& s, FrontLines& out) const {
    const std::uint64_t line_no = r.line_no;
    const std::vector<Field>& args = r.args;
    const Field& major = r.major;
    auto fail = [&](std::uint32_t column, const std::string& why) { r.fail(column, why); };
    auto numbers = [&](std::size_t from, std::size_t count) { return r.numbers(from, count); };
    const std::uint32_t end_column = r.end_column;
    if (args.size() != 3 && args.size() != 6)
        fail(args.empty() ? end_column : args.back().column, "GOTO needs x,y,z or x,y,z,i,j,k (" + std::to_string(args.size()) + " values)");
    const auto v = numbers(0, args.size());
    const Eigen::Vector3d tip(v[0], v[1], v[2]);
    Eigen::Vector3d axis = s.axis;
    if (args.size() == 6) {
        if (!s.multax) fail(args[3].column, "a tool axis on GOTO after MULTAX/OFF");
        const Eigen::Vector3d ijk(v[3], v[4], v[5]);
        if (!(ijk.norm() > 1e-9)) fail(args[3].column, "the tool axis i,j,k has length 0");
        axis = ijk.normalized();
    }
    if (!s.rapid && !s.feed) fail(major.column, "a feed move before any FEDRAT (or RAPID)");
    if (s.circle) arc_to(r, tip, axis, s, out);
    else go_to(tip, axis, line_no, s, out);
    s.rapid = false;
}

// The arc from the last position to `tip` about the CIRCLE before it, in chords.
void AptReader::arc_to(const Record& r, const Eigen::Vector3d& tip, const Eigen::Vector3d& axis, State& s, FrontLines& out) const {
    const std::uint64_t line_no = r.line_no;
    const Field& major = r.major;
    auto fail = [&](std::uint32_t column, const std::string& why) { r.fail(column, why); };
    if (!s.tip_known) fail(major.column, "an arc needs a position before it");
    const auto c = *s.circle;
    s.circle.reset();
    const Eigen::Vector3d n = c.axis;
    const Eigen::Vector3d a0 = s.tip - c.centre, a1 = tip - c.centre;
    const Eigen::Vector3d u0 = a0 - a0.dot(n) * n, u1 = a1 - a1.dot(n) * n;
    const double slack = 1e-3 * std::max(1.0, c.radius);  // CL files print 4 decimals
    if (std::abs(u0.norm() - c.radius) > slack || std::abs(u1.norm() - c.radius) > slack)
        fail(major.column, "the arc's start and end are not at the CIRCLE's radius from its centre (line " +
                               std::to_string(c.line_no) + ")");
    double sweep = std::atan2(u0.cross(u1).dot(n), u0.dot(u1));  // counterclockwise about n
    if (sweep < 0) sweep += 2 * kPi;
    if (sweep < 1e-9) sweep = 2 * kPi;  // back to its start: a full circle
    sweep += 2 * kPi * (c.turns - 1);    // TIMES,n: n turns when the GOTO is above its start
    // Chords within the tolerance (sagitta r(1 - cos(step/2))), in the file's unit; before
    // the unit is known, as if it were inches (the finer).
    const double tol = o_.chord_tolerance / s.unit.value_or(25.4);
    const double step = tol >= c.radius ? kPi / 2 : 2 * std::acos(1 - tol / c.radius);
    const double chords = std::ceil(sweep / std::min(step, kPi / 2));
    if (chords > 1e6) fail(major.column, "the arc needs more than 1e6 chords at this tolerance");
    const int count = int(chords);
    const double h0 = a0.dot(n), h1 = a1.dot(n);
    const Eigen::Vector3d v0 = u0 / u0.norm(), w0 = n.cross(v0);
    const Eigen::Vector3d ax0 = s.axis;
    const double turn = std::acos(std::clamp(ax0.dot(axis), -1.0, 1.0));
    for (int k = 1; k <= count; ++k) {
        const double f = double(k) / count, t = sweep * f;
        Eigen::Vector3d p = c.centre + c.radius * (std::cos(t) * v0 + std::sin(t) * w0) + (h0 + (h1 - h0) * f) * n;
        if (k == count) p = tip;
        // The tool axis turns along the great circle from its start to the GOTO's.
        Eigen::Vector3d ax = axis;
        if (k < count && turn > 1e-12)
            ax = (std::sin((1 - f) * turn) * ax0 + std::sin(f * turn) * axis) / std::sin(turn);
        go_to(p, ax.normalized(), line_no, s, out);
    }
}

void AptReader::fedrat(const Record& r, State& s, FrontLines& out) const {
    const std::vector<Field>& args = r.args;
    auto fail = [&](std::uint32_t column, const std::string& why) { r.fail(column, why); };
    auto number = [&](const Field& f) { return r.number(f); };
    const std::uint32_t end_column = r.end_column;
    // FEDRAT/f, FEDRAT/IPM,f, FEDRAT/MMPM,f or FEDRAT/f,IPM (NX writes the unit first).
    std::optional<double> unit_mm;
    std::optional<Field> value;
    for (const Field& f : args) {
        const std::string u = upper(f.text);
        if (u == "IPM") unit_mm = 25.4;
        else if (u == "MMPM") unit_mm = 1.0;
        else if (u == "IPR" || u == "MMPR") fail(f.column, "feed per revolution (" + u + ") has no meaning without a spindle: give IPM or MMPM");
        else if (value) fail(f.column, "FEDRAT has one feed value");
        else value = f;
    }
    if (!value) fail(end_column, "FEDRAT needs a feed value");
    const double v = number(*value);
    if (!(v > 0)) fail(value->column, "the feed must be positive");
    if (unit_mm && !s.unit) set_unit(*unit_mm, s, out);  // a feed in inches/min: a program in inches
    const double f = unit_mm ? v * *unit_mm / *s.unit : v;
    if (!s.feed || *s.feed != f) s.feed_written = false;
    s.feed = f;
}

void AptReader::circle(const Record& r, State& s) const {
    const std::uint64_t line_no = r.line_no;
    const std::vector<Field>& args = r.args;
    auto fail = [&](std::uint32_t column, const std::string& why) { r.fail(column, why); };
    auto number = [&](const Field& f) { return r.number(f); };
    auto numbers = [&](std::size_t from, std::size_t count) { return r.numbers(from, count); };
    const std::uint32_t end_column = r.end_column;
    if (args.size() < 7) fail(args.empty() ? end_column : args.back().column, "CIRCLE needs xc,yc,zc,i,j,k,r");
    const auto v = numbers(0, 7);
    const Eigen::Vector3d n(v[3], v[4], v[5]);
    if (!(n.norm() > 1e-9)) fail(args[3].column, "the CIRCLE's axis i,j,k has length 0");
    if (!(v[6] > 0)) fail(args[6].column, "the CIRCLE's radius must be positive");
    // NX CLSF: CIRCLE/x,y,z,i,j,k,r,t,f,d,e[,TIMES,n]: tolerance, its inner share, the tool's
    // diameter and corner radius (numbers, not used), then the turns of a helix.
    int turns = 1;
    for (std::size_t i = 7; i < args.size(); ++i) {
        if (upper(args[i].text) == "TIMES") {
            if (i + 2 != args.size()) fail(args[i].column, "TIMES needs one whole number of turns after it, and ends the CIRCLE");
            const double t = number(args[i + 1]);
            if (t < 1 || t != std::floor(t) || t > kAptMaxTurns)
                fail(args[i + 1].column, "TIMES: the helix's turns must be a whole number from 1 to " + std::to_string(kAptMaxTurns));
            turns = int(t);
            break;
        }
        number(args[i]);
    }
    s.circle = State::Circle{Eigen::Vector3d(v[0], v[1], v[2]), n.normalized(), v[6], line_no, turns};
}

bool AptReader::setting(const Record& r, State& s, FrontLines& out) const {
    const std::string& word = r.word;
    const std::vector<Field>& args = r.args;
    const Field& major = r.major;
    auto fail = [&](std::uint32_t column, const std::string& why) { r.fail(column, why); };
    auto number = [&](const Field& f) { return r.number(f); };
    auto comment = [&] { emit(s, out, r.line_no, "; " + std::string(r.all.text)); };
    const std::uint32_t end_column = r.end_column;
    if (word == "UNITS") {
        if (args.size() != 1) fail(end_column, "UNITS needs INCHES or MM");
        const std::string u = upper(args[0].text);
        double mm;
        if (u == "INCHES" || u == "INCH") mm = 25.4;
        else if (u == "MM") mm = 1.0;
        else fail(args[0].column, "UNITS/" + std::string(args[0].text) + ": expected INCHES or MM"), mm = 1;
        if (s.unit && *s.unit != mm) fail(args[0].column, "the units change in the middle of the file");
        if (!s.unit) set_unit(mm, s, out);
        return true;
    }
    if (word == "MULTAX") {
        const std::string u = args.empty() ? "ON" : upper(args[0].text);
        if (args.size() > 1 || (u != "ON" && u != "OFF")) fail(args.empty() ? end_column : args[0].column, "MULTAX takes ON or OFF");
        s.multax = u == "ON";
        if (!s.multax) s.axis = Eigen::Vector3d::UnitZ();
        return true;
    }
    if (word == "LOAD") {
        if (args.size() < 2 || upper(args[0].text) != "TOOL") fail(args.empty() ? end_column : args[0].column, "LOAD needs TOOL,n");
        const double n = number(args[1]);
        if (n < 0 || n != std::floor(n)) fail(args[1].column, "the tool number must be a whole number >= 0");
        comment();  // a printer has one nozzle: the tool change is noted, not sent
        return true;
    }
    if (word == "TOOL PATH") {
        if (s.in_path) fail(major.column, "TOOL PATH inside a TOOL PATH (no END-OF-PATH before it)");
        s.in_path = true;
        comment();
        return true;
    }
    if (word == "END-OF-PATH") {
        if (!s.in_path) fail(major.column, "END-OF-PATH without a TOOL PATH");
        s.in_path = false;
        s.rapid = false;
        comment();
        return true;
    }
    if (word == "FINI") {
        s.finished = true;
        comment();
        return true;
    }
    if (word == "PAINT" || word == "TLDATA" || word == "MSYS" || word == "PARTNO") {
        comment();  // display colours, cutter shape, the frame the coordinates are already in
        return true;
    }
    return false;
}

void AptReader::record(std::string_view line, std::uint64_t line_no, State& s, FrontLines& out) const {
    auto fail = [&](std::uint32_t column, const std::string& why) -> void {
        throw InputError(o_.input_name, line_no, column, why);
    };
    const Field all = trim(line, 1);
    if (all.text.empty()) return;
    if (all.text.rfind("$$", 0) == 0) {
        emit(s, out, line_no, "; " + std::string(trim(all.text.substr(2), 1).text));
        return;
    }
    if (!s.seen_record && (listing_rule(all.text) || listing_header(all.text))) {
        if (!listing_rule(all.text)) emit(s, out, line_no, "; " + std::string(all.text));
        return;
    }
    s.seen_record = true;
    if (s.finished) fail(all.column, "record after FINI");
    // The major word, then the fields after '/', split at commas.
    const std::size_t slash = all.text.find('/');
    const Field major = trim(all.text.substr(0, slash), all.column);
    const std::string word = upper(major.text);
    std::vector<Field> args;
    if (slash != std::string_view::npos) {
        std::string_view rest = all.text.substr(slash + 1);
        std::uint32_t col = std::uint32_t(all.column + slash + 1);
        // A trailing "$$ comment" on a record is dropped.
        if (const auto cc = rest.find("$$"); cc != std::string_view::npos) rest = rest.substr(0, cc);
        while (true) {
            const std::size_t comma = rest.find(',');
            args.push_back(trim(rest.substr(0, comma), col));
            if (comma == std::string_view::npos) break;
            col += std::uint32_t(comma + 1);
            rest.remove_prefix(comma + 1);
        }
    }
    const Record r{o_.input_name, line_no, all, major, word, std::move(args), slash, std::uint32_t(all.column + all.text.size())};

    if (s.circle && word != "GOTO" && word != "PAINT")
        fail(major.column, "CIRCLE must be followed by the GOTO that ends its arc, not " + word);

    if (word == "GOTO") return goto_record(r, s, out);
    if (word == "RAPID") {
        if (!r.args.empty()) fail(r.args.front().column, "RAPID takes no values");
        s.rapid = true;
        return;
    }
    if (word == "FEDRAT") return fedrat(r, s, out);
    if (word == "CIRCLE") return circle(r, s);
    if (setting(r, s, out)) return;
    // NX's listing trailer after the last tool path ("Tool Path Listing has 388 lines.").
    if (!s.in_path && slash == std::string_view::npos && upper(all.text).rfind("TOOL PATH LISTING HAS ", 0) == 0) {
        emit(s, out, line_no, "; " + std::string(all.text));
        return;
    }
    fail(major.column, "CL record '" + (word.empty() ? std::string(all.text.substr(0, 20)) : word) +
                           "' is not supported (GOTO, RAPID, FEDRAT, CIRCLE, UNITS, MULTAX, LOAD/TOOL, $$, TOOL PATH, END-OF-PATH, FINI)");
}

}  // namespace xlate5
