// SPDX-License-Identifier: GPL-3.0-or-later
// The report's plot (--plot FILE.svg): tip deviation along the file. What it may call: see report.hpp.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "translators/inspect/report.hpp"
#include "translators/inspect/report_json.hpp"

namespace xlate5 {

namespace {

// Text inside an SVG element: XML's rules (json_escape lets '&' and '<' through). A
// control byte is not allowed in XML 1.0 at all: shown as U+FFFD.
std::string xml_escape(const std::string& s) {
    std::string o;
    for (char c : s) {
        switch (c) {
            case '&': o += "&amp;"; break;
            case '<': o += "&lt;"; break;
            case '>': o += "&gt;"; break;
            case '"': o += "&quot;"; break;
            case '\'': o += "&apos;"; break;
            default:
                if (static_cast<unsigned char>(c) < 0x20 && c != '\t') o += "\xEF\xBF\xBD";
                else o += c;
        }
    }
    return o;
}

// A step of 1, 2 or 5 times a power of ten giving about `count` ticks over `range`.
double nice_step(double range, int count) {
    const double raw = range / count;
    const double decade = std::pow(10.0, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0})
        if (m * decade >= raw) return m * decade;
    return 10 * decade;
}

// A tick label as a person writes it: 0.001, 0.01, 2500, 1e-05 only below 0.0001.
std::string tick_text(double v) {
    char b[48];
    if (v != 0 && std::abs(v) < 1e-4) std::snprintf(b, sizeof b, "%.0e", v);
    else std::snprintf(b, sizeof b, "%.10g", v);
    return b;
}

}  // namespace

std::string DeviationReport::svg() const {
    // Tip deviation (mm) along the file on a log scale (deviations span decades, the tolerance
    // among them), with the tolerance as a line; 900 x 300 plot area.
    const std::vector<DeviationSeries::Point>& series = stats.series.points();
    const double W = 900, H = 300, left = 80, top = 30;
    double vmax = std::max(tolerance_, stats.tip.max), vmin = tolerance_ / 100;
    for (const DeviationSeries::Point& p : series)
        if (p.tip > 0) vmin = std::min(vmin, p.tip);
    if (!(vmax > 0) || !std::isfinite(vmax)) vmax = std::pow(10.0, Distribution::kLogMax);  // an infinite deviation is drawn at the top
    if (!(vmin > 0)) vmin = vmax / 1e3;
    // At most four decades under the tolerance: below that a deviation is nothing to look at.
    const double lo = std::max({Distribution::kLogMin, std::floor(std::log10(vmin)), std::floor(std::log10(tolerance_)) - 4}), hi = std::max(lo + 1, std::ceil(std::log10(vmax) + 1e-9));
    const double first = series.empty() ? 0 : double(series.front().first_line);
    const double last = series.empty() ? 1 : std::max(double(series.back().last_line), first + 1);
    auto X = [&](double line) { return left + (line - first) / (last - first) * W; };
    auto Y = [&](double v) {  // zero and below the range at the bottom
        const double l = v > 0 ? std::clamp(std::log10(v), lo, hi) : lo;
        return top + H - (l - lo) / (hi - lo) * H;
    };
    const std::string font = "font-family=\"sans-serif\" font-size=\"11\"";
    std::string o;
    o += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + json_number(W + left + 30) + "\" height=\"" + json_number(H + top + 60) + "\">\n";
    o += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    o += "<text x=\"" + json_number(left) + "\" y=\"18\" font-family=\"sans-serif\" font-size=\"13\">" + xml_escape(file_) + " on " +
         xml_escape(machine_) + ": largest tip deviation from the programmed path per move (max " + json_number(stats.tip.max) + " mm at line " +
         std::to_string(stats.tip.max_line) + ")</text>\n";
    // Decades on the deviation axis, with grid lines; the x axis in 1-2-5 steps of input lines.
    for (double d = lo; d <= hi + 1e-9; d += 1) {
        const double v = std::pow(10.0, d);
        o += "<line class=\"grid\" x1=\"" + json_number(left) + "\" y1=\"" + json_number(Y(v)) + "\" x2=\"" + json_number(left + W) + "\" y2=\"" + json_number(Y(v)) +
             "\" stroke=\"#ddd\"/>\n";
        o += "<text class=\"ytick\" x=\"" + json_number(left - 6) + "\" y=\"" + json_number(Y(v) + 4) + "\" " + font + " text-anchor=\"end\">" + tick_text(v) +
             "</text>\n";
    }
    const double step = nice_step(last - first, 8);
    for (double l = std::ceil(first / step) * step; l <= last + 1e-9; l += step) {
        o += "<line x1=\"" + json_number(X(l)) + "\" y1=\"" + json_number(top + H) + "\" x2=\"" + json_number(X(l)) + "\" y2=\"" + json_number(top + H + 5) +
             "\" stroke=\"black\"/>\n";
        o += "<text class=\"xtick\" x=\"" + json_number(X(l)) + "\" y=\"" + json_number(top + H + 18) + "\" " + font + " text-anchor=\"middle\">" +
             tick_text(l) + "</text>\n";
    }
    o += "<line x1=\"" + json_number(left) + "\" y1=\"" + json_number(top + H) + "\" x2=\"" + json_number(left + W) + "\" y2=\"" + json_number(top + H) + "\" stroke=\"black\"/>\n";
    o += "<line x1=\"" + json_number(left) + "\" y1=\"" + json_number(top) + "\" x2=\"" + json_number(left) + "\" y2=\"" + json_number(top + H) + "\" stroke=\"black\"/>\n";
    o += "<text x=\"16\" y=\"" + json_number(top + H / 2) + "\" font-family=\"sans-serif\" font-size=\"12\" text-anchor=\"middle\" transform=\"rotate(-90 16 " +
         json_number(top + H / 2) + ")\">tip deviation, mm (log scale)</text>\n";
    o += "<text x=\"" + json_number(left + W / 2) + "\" y=\"" + json_number(top + H + 40) +
         "\" font-family=\"sans-serif\" font-size=\"12\" text-anchor=\"middle\">input line (red: tolerance " + json_number(tolerance_) + " mm)</text>\n";
    o += "<line x1=\"" + json_number(left) + "\" y1=\"" + json_number(Y(tolerance_)) + "\" x2=\"" + json_number(left + W) + "\" y2=\"" + json_number(Y(tolerance_)) +
         "\" stroke=\"red\" stroke-dasharray=\"6,4\"/>\n";
    o += "<polyline fill=\"none\" stroke=\"steelblue\" stroke-width=\"1\" points=\"";
    for (const DeviationSeries::Point& p : series) o += json_number(X(0.5 * double(p.first_line + p.last_line))) + "," + json_number(Y(p.tip)) + " ";
    o += "\"/>\n</svg>\n";
    return o;
}

}  // namespace xlate5
