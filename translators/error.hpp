// Errors that carry the place they come from, so every message names file, line and cause.
// No stage: thrown by every stage, caught by the front door's caller. Calls nothing.
#pragma once
#include <cstdint>
#include <stdexcept>
#include <string>

namespace xlate5 {

// Bad G-code input: formatted as "file:line:column: message".
class InputError : public std::runtime_error {
public:
    InputError(std::string file, std::uint64_t line, std::uint32_t column, const std::string& message)
        : std::runtime_error(file + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " + message),
          file_(std::move(file)), line_(line), column_(column), message_(message) {}
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
        : std::runtime_error(message), column_(column) {}
    std::uint32_t column() const { return column_; }

private:
    std::uint32_t column_;
};

// A broken machine file or machine parameter: "path:line: key: message".
class MachineError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// The output could not be written or the input could not be opened.
class IoError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

}  // namespace xlate5
