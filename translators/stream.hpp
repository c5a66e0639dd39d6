// A whole stream through the library: the line reader (first stage) -> the front door ->
// the sink. May call: line_reader, input_front, the front door (translator.hpp), output_sink.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>

#include "translators/line_reader.hpp"
#include "translators/output_sink.hpp"

namespace xlate5 {

class Translator;

struct StreamStats {
    std::uint64_t lines_in = 0;
    std::uint64_t bytes_in = 0;
    std::uint64_t bytes_out = 0;
    std::uint64_t lines_out = 0;
};

class InputFront;

// Runs every line of `reader` through `translator` into `sink`.
StreamStats translate_stream(LineReader& reader, Translator& translator, OutputSink& sink);
// The same through an input front (CL data, waypoint tables, or G-code detected by content).
StreamStats translate_stream(LineReader& reader, InputFront& front, OutputSink& sink);

}  // namespace xlate5
