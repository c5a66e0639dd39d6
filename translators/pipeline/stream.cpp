// SPDX-License-Identifier: GPL-3.0-or-later
// The loop from the line reader through the front door to the sink.
// What it may call: see stream.hpp.
#include "translators/pipeline/stream.hpp"

#include <algorithm>
#include <cstring>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "translators/error.hpp"
#include "translators/inputs/input_front.hpp"
#include "translators/pipeline/translator.hpp"

namespace xlate5 {

namespace {
constexpr std::size_t kFlushAt = 1u << 18;
}  // namespace

// Line ends in a block of output. With SSE2 (every x86-64): 16 bytes a step, each compare's
// 0xFF bytes (-1) subtracted into byte counters summed before they can wrap; a call of memchr
// per output line (about 50 bytes) costs twice that. Elsewhere memchr, a call per line.
std::uint64_t count_newlines_memchr(std::string_view text) {
    std::uint64_t n = 0;
    const char* p = text.data();
    const char* const end = p + text.size();
    while (p != end) {
        const void* nl = std::memchr(p, '\n', std::size_t(end - p));
        if (!nl) break;
        ++n;
        p = static_cast<const char*>(nl) + 1;
    }
    return n;
}

std::uint64_t count_newlines(std::string_view text) {
#if defined(__SSE2__)
    std::uint64_t n = 0;
    const char* p = text.data();
    std::size_t left = text.size();
    const __m128i newline = _mm_set1_epi8('\n');
    while (left >= 16) {
        // At most 255 steps into the byte counters: none of them can wrap.
        const std::size_t steps = std::min<std::size_t>(left / 16, 255);
        __m128i counts = _mm_setzero_si128();
        for (std::size_t i = 0; i < steps; ++i, p += 16)
            counts = _mm_sub_epi8(counts, _mm_cmpeq_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)), newline));
        const __m128i sums = _mm_sad_epu8(counts, _mm_setzero_si128());  // two 64-bit sums of 8 bytes
        n += std::uint64_t(_mm_cvtsi128_si64(sums)) + std::uint64_t(_mm_cvtsi128_si64(_mm_unpackhi_epi64(sums, sums)));
        left -= steps * 16;
    }
    for (; left > 0; --left, ++p) n += *p == '\n';
    return n;
#else
    return count_newlines_memchr(text);
#endif
}

StreamStats translate_stream(LineReader& reader, Translator& translator, OutputSink& sink, bool streaming,
                             const std::function<void(const StreamStats&)>& on_read,
                             const std::function<void(std::string_view)>& on_write) {
    FrontOptions o;
    o.format = InputFormat::GCode;
    InputFront front(translator, o);
    return translate_stream(reader, front, sink, streaming, on_read, on_write);
}

StreamStats translate_stream(LineReader& reader, InputFront& front, OutputSink& sink, bool streaming,
                             const std::function<void(const StreamStats&)>& on_read,
                             const std::function<void(std::string_view)>& on_write,
                             const std::function<bool(std::string_view, std::string&)>& on_first_line) {
    Translator& translator = front.translator();
    StreamStats stats;
    std::string out;
    out.reserve(kFlushAt + 4096);
    std::string_view line;
    std::uint64_t seen = 0;  // bytes read when on_read was last called
    auto flush = [&] {
        if (on_write) on_write(out);
        sink.write(out);
        stats.bytes_out += out.size();
        stats.lines_out += count_newlines(out);
        out.clear();
    };
    translator.set_lookback(Translator::kDefaultLookback);  // a limit further on can be unwound on an earlier travel move
    // The output bound (docs/limits.md), checked once a line: the bytes written and pending
    // against the floor plus the input's share.
    const auto check_output = [&](std::string_view at) {
        if (stats.bytes_out + out.size() <= kOutputFloor + kOutputPerInputByte * reader.bytes_consumed()) return;
        const std::size_t first = at.find_first_not_of(" \t");
        throw InputError(reader.name(), std::max<std::uint64_t>(reader.line_number(), 1),
                         std::uint32_t(first == std::string_view::npos ? 1 : first + 1),
                         "the output would pass its bound, " + std::to_string(kOutputFloor + kOutputPerInputByte * reader.bytes_consumed()) +
                             " bytes for the first " + std::to_string(reader.bytes_consumed()) + " bytes of input (16 MiB + " +
                             std::to_string(kOutputPerInputByte) + " a byte, docs/limits.md): arcs with many turns (P) or long "
                             "splits; give fewer turns or a coarser --tolerance");
    };
    while (reader.next(line)) {
        if (!on_first_line || reader.line_number() != 1 || on_first_line(line, out)) front.feed(line, reader.line_number(), out);
        if (stats.bytes_out + out.size() > kOutputFloor) check_output(line);  // under the floor, within the bound
        if (out.size() >= kFlushAt || (streaming && !out.empty() && !reader.has_line())) flush();
        if (on_read && reader.bytes_read() != seen) {
            seen = reader.bytes_read();
            stats.lines_in = reader.line_number();
            stats.bytes_in = seen;
            on_read(stats);
        }
    }
    front.finish(reader.line_number(), out);
    check_output({});
    flush();
    stats.lines_in = reader.line_number();
    stats.bytes_in = reader.bytes_read();
    return stats;
}

}  // namespace xlate5
