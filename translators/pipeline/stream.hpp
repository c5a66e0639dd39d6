// SPDX-License-Identifier: GPL-3.0-or-later
// A whole stream through the library: the line reader (first stage) -> the front door ->
// the sink. May call: line_reader, input_front, the front door (translator.hpp), output_sink.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

#include "translators/inputs/line_reader.hpp"
#include "translators/pipeline/output_sink.hpp"

namespace xlate5 {

class Translator;

struct StreamStats {
    std::uint64_t lines_in = 0;
    std::uint64_t bytes_in = 0;
    std::uint64_t bytes_out = 0;
    std::uint64_t lines_out = 0;
};

class InputFront;

// The output of a translation is bounded by its input (docs/limits.md): at most kOutputFloor
// bytes plus kOutputPerInputByte for each byte of the lines read so far. Real files come out at
// 0.5 to 7 times their size; a full circle of 100 mm radius in one G2 is about 370 times its
// line's, at the default tolerance. Pieces per line (kMaxPiecesPerLine) bound one line; this
// bounds the file, so a few KB of arcs with many turns cannot write hundreds of MB. The line at
// which the output passes it is refused (InputError, at its first word).
inline constexpr std::uint64_t kOutputFloor = 16u << 20;
inline constexpr std::uint64_t kOutputPerInputByte = 1024;

// Runs every line of `reader` through `front` (CL data, waypoint tables, or G-code detected by
// content) into `sink`. Output is written in large blocks; with `streaming` (the input is a pipe
// or a terminal) also whenever the input has no further line at hand, so a filter between a
// sender and a printer never holds decided output while it waits for input (the look-back still
// holds what it may translate again). `on_read`, when given, is called with the counts so far
// once per block of input read, never per line; `on_write` with each block of output as it goes
// to the sink (whole lines). `on_first_line`, when given, sees the first line before it is fed:
// it may append to the output (a header) or throw, and returns whether the line is fed.
StreamStats translate_stream(LineReader& reader, InputFront& front, OutputSink& sink, bool streaming = false,
                             const std::function<void(const StreamStats&)>& on_read = {},
                             const std::function<void(std::string_view)>& on_write = {},
                             const std::function<bool(std::string_view, std::string&)>& on_first_line = {});
// The same for G-code.
StreamStats translate_stream(LineReader& reader, Translator& translator, OutputSink& sink, bool streaming = false,
                             const std::function<void(const StreamStats&)>& on_read = {},
                             const std::function<void(std::string_view)>& on_write = {});

// The line ends ('\n') in a block of output (StreamStats::lines_out), and the same counted with
// memchr (the general path the tests hold it against).
std::uint64_t count_newlines(std::string_view text);
std::uint64_t count_newlines_memchr(std::string_view text);

}  // namespace xlate5
