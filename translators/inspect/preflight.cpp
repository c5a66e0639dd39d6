// SPDX-License-Identifier: GPL-3.0-or-later
// The pre-flight estimate. What it may call: see preflight.hpp; the model: docs/preflight.md.
#include "translators/inspect/preflight.hpp"

#include "translators/pipeline/motion.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>

namespace xlate5 {

namespace {

constexpr double kMinPlannerSpeed = 0.05;  // mm/s: Marlin's MINIMUM_PLANNER_SPEED
constexpr std::uint64_t kMergeLines = 50;  // drains this close together are one range

std::string num(double v) {
    if (!std::isfinite(v)) return "null";
    char b[32];
    std::snprintf(b, sizeof b, "%.6g", v);
    return b;
}

// A trapezoid: from `v0` up to at most `v` and down to `v1` over `length` at acceleration `a`.
double trapezoid(double length, double v0, double v1, double v, double a) {
    if (length <= 0 || v <= 0) return 0;
    const double up = (v * v - v0 * v0) / (2 * a), down = (v * v - v1 * v1) / (2 * a);
    if (up + down <= length) return (v - v0) / a + (v - v1) / a + (length - up - down) / v;
    const double peak = std::sqrt(std::max(0.0, (2 * a * length + v0 * v0 + v1 * v1) / 2));
    return std::max(0.0, (peak - v0) / a) + std::max(0.0, (peak - v1) / a);
}

}  // namespace

Preflight::Preflight(const Machine& machine, double baud) : m_(machine), link_{baud / 10}, q_(machine.home_joints()) {}

namespace {

// The command of a line ("G4", "M109": its letter and number, leading zeros read as the
// firmware reads them), and whether it is `letter` `number`.
bool is_command(std::string_view text, char letter, int number) {
    if (text.size() < 2 || text[0] != letter) return false;
    int v = 0;
    std::size_t i = 1;
    for (; i < text.size() && std::isdigit(static_cast<unsigned char>(text[i])); ++i) v = 10 * v + (text[i] - '0');
    return i > 1 && v == number && (i == text.size() || text[i] == ' ');
}

// Each word of `text` from `from` on, as f(letter, value): words are split at spaces, and one
// whose number does not read is skipped.
template <class F>
void for_each_word(std::string_view text, std::size_t from, F&& f) {
    for (std::size_t i = from; i < text.size();) {
        if (text[i] == ' ') {
            ++i;
            continue;
        }
        const char letter = text[i];
        std::size_t end = text.find(' ', i);
        if (end == std::string_view::npos) end = text.size();
        std::string_view word = text.substr(i + 1, end - i - 1);
        i = end;
        // from_chars: correctly rounded as strtod, a tenth of its cost (strtod was half the scan's).
        if (!word.empty() && word[0] == '+') word.remove_prefix(1);
        double v = 0;
        if (std::from_chars(word.data(), word.data() + word.size(), v).ec != std::errc() || !std::isfinite(v)) continue;
        f(letter, v);
    }
}

}  // namespace

void PlannerModel::wait(double seconds, double link, std::uint64_t line) {
    finish();
    prev_exit_ = 0;
    // The wait starts when the last block has ended and the line has arrived.
    clock_ = std::max(clock_, link) + seconds;
    done_ += seconds;
    if (executed_) executed_(line, seconds);
}

void Preflight::scan(std::string_view output) {
    while (!output.empty()) {
        const auto nl = output.find('\n');
        if (nl == std::string_view::npos) {
            pending_.append(output);
            return;
        }
        if (!pending_.empty()) {
            pending_.append(output.substr(0, nl));
            line(pending_);
            pending_.clear();
        } else {
            line(output.substr(0, nl));
        }
        output.remove_prefix(nl + 1);
    }
}

void Preflight::line(std::string_view l) {
    ++lines_;
    // What a host sends: the line without its comment, numbered and checksummed.
    const auto semi = l.find(';');
    std::string_view text = l.substr(0, semi);
    while (!text.empty() && (text.back() == ' ' || text.back() == '\r' || text.back() == '\t')) text.remove_suffix(1);
    while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
    if (text.empty()) return;
    ++link_.sent;
    const std::string framed = "N" + std::to_string(link_.sent) + " " + std::string(text);
    unsigned char sum = 0;
    for (char c : framed) sum ^= static_cast<unsigned char>(c);
    const std::uint64_t bytes = framed.size() + 1 + std::to_string(sum).size() + 1;
    link_.bytes += bytes;
    link_.line_seconds = double(bytes) / link_.bytes_per_s;
    link_.at += link_.line_seconds;
    if (!text.empty() && (text[0] == 'G' || text[0] == 'M')) {
        if (is_command(text, 'G', 4)) {
            // Marlin (and RepRapFirmware): S seconds over P milliseconds; Klipper: P alone.
            const bool seconds_word = m_.dialect.firmware != FirmwareDialect::Klipper;
            std::optional<double> s, p;  // the first of each
            for_each_word(text, text.find(' '), [&](char letter, double v) {
                if (letter == 'S' && seconds_word && !s) s = v;
                if (letter == 'P' && !p) p = v;
            });
            const double d = std::max(0.0, s ? *s : p ? *p / 1000 : 0.0);
            ++waits_.dwells, waits_.dwell_seconds += d;
            planner_.wait(d, link_.at, lines_);
            return;
        }
        if (is_command(text, 'M', 400)) return planner_.wait(0, link_.at, lines_);
        if (is_command(text, 'M', 109) || is_command(text, 'M', 190) || is_command(text, 'M', 191) || is_command(text, 'M', 116)) {
            ++waits_.heat_waits;
            return;
        }
    }
    if (text.size() < 3 || text[0] != 'G') return;
    if (text.substr(0, 3) == "G28" && (text.size() == 3 || text[3] == ' ')) {
        bool named = false;
        for (std::size_t j = 0; j < q_.size(); ++j)
            if (text.find(m_.joints[j].output, 3) != std::string_view::npos) q_[j] = m_.joints[j].home, named = true;
        if (!named) q_ = m_.home_joints();
        return;
    }
    const bool move = (text[1] == '0' || text[1] == '1') && text[2] == ' ';
    const bool set = text.substr(0, 4) == "G92 ";
    if (!move && !set) return;
    std::vector<double> to = q_;
    for_each_word(text, 3, [&](char letter, double v) {
        if (letter == 'F' && move) f_ = v;
        for (std::size_t j = 0; j < to.size(); ++j)
            if (m_.joints[j].output == letter) to[j] = v;
    });
    if (move) add_move(q_, to, f_);
    q_ = to;
}

void Preflight::add_move(const std::vector<double>& from, const std::vector<double>& to, double feed) {
    const double length = firmware_length(m_, from, to);
    if (!(length > 0) || !(feed > 0)) return;
    ++moves_;
    PlannerModel::Block b;
    b.length = length;
    b.line = lines_;
    // The feed (mm/min of the dialect's length; G93 files: 1/min) capped by each joint's max_feed.
    double v = m_.dialect.inverse_time ? length * feed / 60 : feed / 60;
    bool linear = false;
    for (std::size_t j = 0; j < to.size(); ++j) linear = linear || (!m_.joints[j].rotary && to[j] != from[j]);
    double norm = 0;
    b.unit.assign(to.size(), 0.0);
    for (std::size_t j = 0; j < to.size(); ++j) {
        const double d = to[j] - from[j];
        if (m_.joints[j].max_feed > 0 && d != 0) v = std::min(v, m_.joints[j].max_feed / 60 * length / std::abs(d));
        // The junction's direction: the axes the length counts.
        if (m_.dialect.firmware == FirmwareDialect::MarlinArticulated || !linear || !m_.joints[j].rotary) b.unit[j] = d, norm += d * d;
    }
    for (double& u : b.unit) u /= std::sqrt(norm);
    b.nominal = v;
    if (length / v < m_.planner.min_segment_time) ++short_moves_;
    planner_.add(std::move(b), link_.line_seconds, link_.at);
}

void PlannerModel::add(Block b, double line_seconds, double& link) {
    const double v = b.nominal;
    // Marlin's junction deviation: the speed through the corner from the last block.
    double vj = kMinPlannerSpeed;
    if (!prev_unit_.empty()) {
        double cos_theta = 0;
        for (std::size_t j = 0; j < b.unit.size(); ++j) cos_theta -= prev_unit_[j] * b.unit[j];
        if (cos_theta < -0.999999) vj = v;  // straight on
        else if (cos_theta < 0.999999) {
            const double s = std::sqrt(0.5 * (1 - cos_theta));
            vj = std::sqrt(m_.planner.acceleration * m_.planner.junction_deviation * s / (1 - s));
        }
        vj = std::min({vj, v, window_.empty() ? v : window_.back().nominal});
    }
    b.entry_max = std::max(kMinPlannerSpeed, vj);
    prev_unit_ = b.unit;
    b.bytes_at = 0;
    window_.push_back(std::move(b));
    if (window_.size() > std::size_t(m_.planner.blocks)) plan_and_pop();
    // The line reaches the firmware when the link has sent it and the planner has room: the
    // block `blocks` before it has ended.
    const double room = finished_.size() >= std::size_t(m_.planner.blocks) ? finished_.front() : 0;
    link = std::max(link, room + line_seconds);
    window_.back().bytes_at = link;
}

void PlannerModel::plan_and_pop() {
    // Backward over the horizon: the last block can stop, each entry reachable from the next.
    double exit = 0;
    std::vector<double> entry(window_.size());
    for (std::size_t i = window_.size(); i-- > 0;) {
        const Block& b = window_[i];
        entry[i] = std::min(b.entry_max, std::sqrt(exit * exit + 2 * m_.planner.acceleration * b.length));
        exit = entry[i];
    }
    Block& first = window_.front();
    const double next_entry = window_.size() > 1 ? entry[1] : 0;
    execute(first, next_entry);
    window_.pop_front();
}

void PlannerModel::execute(Block& b, double exit_limit) {
    const double a = m_.planner.acceleration;
    const double v0 = std::min(prev_exit_, b.nominal);
    const double v1 = std::min({exit_limit, b.nominal, std::sqrt(v0 * v0 + 2 * a * b.length)});
    b.time = trapezoid(b.length, v0, v1, b.nominal, a);
    prev_exit_ = v1;
    done_ += b.time;
    if (executed_) executed_(b.line, b.time);
    // The firmware: it starts the block when the last ended and the block has arrived (the
    // first block's wait is the link's start, not a drain).
    if (b.bytes_at > clock_ && !finished_.empty()) {
        const double stall = b.bytes_at - clock_;
        ++drains_, stall_ += stall;
        if (!ranges_.empty() && b.line <= ranges_.back().last + kMergeLines) ranges_.back().last = b.line, ranges_.back().stall += stall;
        else if (ranges_.size() < kMaxRanges) ranges_.push_back({b.line, b.line, stall});
    }
    clock_ = std::max(clock_, b.bytes_at) + b.time;
    finished_.push_back(clock_);
    if (finished_.size() > std::size_t(m_.planner.blocks)) finished_.pop_front();
}

std::string Preflight::json() const {
    const double done = seconds(), need = done > 0 ? double(link_.bytes) / done : 0;
    std::string o = "{\"seconds\": " + num(done) + ", \"minutes\": " + num(done / 60) + ", \"seconds_with_link\": " +
                    num(seconds_with_link()) + ", \"link_bytes_per_s\": " + num(link_.bytes_per_s) + ", \"lines_sent\": " +
                    std::to_string(link_.sent) + ", \"bytes_sent\": " + std::to_string(link_.bytes) + ", \"need_bytes_per_s_mean\": " + num(need) +
                    ", \"moves\": " + std::to_string(moves_) + ", \"moves_under_min_segment_time\": " + std::to_string(short_moves_) +
                    ", \"dwells\": " + std::to_string(waits_.dwells) + ", \"dwell_seconds\": " + num(waits_.dwell_seconds) +
                    ", \"heat_waits_not_included\": " + std::to_string(waits_.heat_waits) + ", \"drains\": " +
                    std::to_string(planner_.drain_count()) + ", \"stall_seconds\": " + num(planner_.stall_seconds()) + ", \"drain_ranges\": [";
    const auto& ranges = planner_.drains();
    for (std::size_t i = 0; i < ranges.size(); ++i)
        o += std::string(i ? ", " : "") + "{\"first_line\": " + std::to_string(ranges[i].first) + ", \"last_line\": " +
             std::to_string(ranges[i].last) + ", \"stall_seconds\": " + num(ranges[i].stall) + "}";
    o += "], \"planner\": {\"acceleration\": " + num(m_.planner.acceleration) + ", \"junction_deviation_mm\": " +
         num(m_.planner.junction_deviation) + ", \"min_segment_time_s\": " + num(m_.planner.min_segment_time) + ", \"blocks\": " +
         std::to_string(m_.planner.blocks) + "}}";
    return o;
}

std::string Preflight::summary() const {
    char b[600];
    const double done = seconds(), need = done > 0 ? double(link_.bytes) / done : 0;
    const std::uint64_t drains = planner_.drain_count();
    std::snprintf(b, sizeof b,
                  "pre-flight: about %.1f min of motion and dwells (acceleration %.0f, junction deviation %.3f mm, %d-block planner); "
                  "the file sends %.0f bytes/s on average against the link's %.0f; %llu moves shorter than %.0f ms; "
                  "%s%.1f min with the link.\n",
                  done / 60, m_.planner.acceleration, m_.planner.junction_deviation, m_.planner.blocks, need, link_.bytes_per_s,
                  static_cast<unsigned long long>(short_moves_), m_.planner.min_segment_time * 1000,
                  drains ? ("the planner's buffer drains " + std::to_string(drains) + " times (first from line " +
                            std::to_string(planner_.drains().front().first) + "), ").c_str()
                          : "the buffer never drains, ",
                  seconds_with_link() / 60);
    std::string out = b;
    if (waits_.dwells || waits_.heat_waits) {
        std::snprintf(b, sizeof b, "pre-flight: %llu dwells (G4) add %.1f s, counted above; %llu waits for heating (M109, M190, M191, M116) are not.\n",
                      static_cast<unsigned long long>(waits_.dwells), waits_.dwell_seconds, static_cast<unsigned long long>(waits_.heat_waits));
        out += b;
    }
    return out;
}

}  // namespace xlate5
