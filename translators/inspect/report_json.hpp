// SPDX-License-Identifier: GPL-3.0-or-later
// The report's writers' number and string forms (report_json.cpp writes the JSON, report_plot.cpp
// the SVG plot).
#pragma once
#include <string>

namespace xlate5 {

// JSON has no inf or NaN: an infinite value is written as 1e999 (a valid JSON number that
// parsers read as infinity), NaN as null; others with 6 significant digits.
std::string json_number(double v);
// A JSON string's contents: quotes and backslashes escaped, control bytes as \u00XX.
std::string json_escape(const std::string& s);

}  // namespace xlate5
