// SPDX-License-Identifier: GPL-3.0-or-later
// Arithmetic over named machine parameters ("-la", "lb + 2", "z_offset*2"), so a machine file
// states each measured value once and the command line can override it. Part of reading a
// machine (machine_file.cpp). Calls nothing.
#pragma once
#include <map>
#include <string>

namespace xlate5 {

// Deepest nesting of parentheses and unary signs an expression may have: machine files need a
// handful; the bound keeps a hostile file from exhausting the stack of the recursive parser.
inline constexpr int kMaxExpressionDepth = 64;

// Evaluates + - * / unary minus, parentheses, numbers and parameter names.
// Throws std::invalid_argument with a message naming the problem.
double evaluate_expression(const std::string& text, const std::map<std::string, double>& params);

}  // namespace xlate5
