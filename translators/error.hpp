// SPDX-License-Identifier: GPL-3.0-or-later
// Errors that carry the place they come from, so every message names file, line and cause.
// No stage: thrown by every stage, caught by the front door's caller. Calls nothing.
#pragma once
#include <cstdint>
#include <stdexcept>
#include <string>

namespace xlate5 {

// A message quotes its input (a record, a word, a file name): a control byte in it would reach
// the user's terminal as is (ESC starts a terminal command, NUL cuts the line in many viewers),
// so each is written as \xHH. Newline and tab stay: messages of several lines use them.
inline std::string printable(std::string s) {
    static constexpr char kHex[] = "0123456789abcdef";
    std::size_t bad = 0;
    for (char c : s)
        if ((static_cast<unsigned char>(c) < 0x20 && c != '\n' && c != '\t') || c == 0x7F) ++bad;
    if (bad == 0) return s;
    std::string o;
    o.reserve(s.size() + 3 * bad);
    for (char c : s) {
        const auto u = static_cast<unsigned char>(c);
        if ((u < 0x20 && c != '\n' && c != '\t') || u == 0x7F) {
            o += "\\x";
            o += kHex[u >> 4];
            o += kHex[u & 15];
        } else {
            o += c;
        }
    }
    return o;
}

// Bad G-code input: formatted as "file:line:column: message".
class InputError : public std::runtime_error {
public:
    InputError(std::string file, std::uint64_t line, std::uint32_t column, const std::string& message)
        : std::runtime_error(printable(file + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " + message)),
          file_(std::move(file)), line_(line), column_(column), message_(printable(message)) {}
    const std::string& file() const { return file_; }
    std::uint64_t line() const { return line_; }
    std::uint32_t column() const { return column_; }
    const std::string& message() const { return message_; }

private:
    std::string file_;
    std::uint64_t line_;
    std::uint32_t column_;
    std::string message_;
};

// A problem found while lexing or interpreting one line, before the file and line are known;
// the stage that reads lines turns it into an InputError.
class LineError : public std::runtime_error {
public:
    LineError(std::uint32_t column, const std::string& message)
        : std::runtime_error(printable(message)), column_(column) {}
    std::uint32_t column() const { return column_; }

private:
    std::uint32_t column_;
};

// A broken machine file or machine parameter: "path:line: key: message".
class MachineError : public std::runtime_error {
public:
    explicit MachineError(const std::string& message) : std::runtime_error(printable(message)) {}
};

// The output could not be written or the input could not be opened.
class IoError : public std::runtime_error {
public:
    explicit IoError(const std::string& message) : std::runtime_error(printable(message)) {}
};

}  // namespace xlate5
