// The loop from the line reader through the front door to the sink.
// What it may call: see stream.hpp.
#include "translators/stream.hpp"

#include <algorithm>
#include <cstring>

#include "translators/input_front.hpp"
#include "translators/translator.hpp"

namespace xlate5 {

namespace {
constexpr std::size_t kFlushAt = 1u << 18;

// Line ends in a block of output, found with memchr (the C library's vector search: a move
// line is about 50 bytes, so a call per line costs less than testing every byte, or every eight).
std::uint64_t count_newlines(std::string_view text) {
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
}  // namespace

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
    while (reader.next(line)) {
        if (!on_first_line || reader.line_number() != 1 || on_first_line(line, out)) front.feed(line, reader.line_number(), out);
        if (out.size() >= kFlushAt || (streaming && !out.empty() && !reader.has_line())) flush();
        if (on_read && reader.bytes_read() != seen) {
            seen = reader.bytes_read();
            stats.lines_in = reader.line_number();
            stats.bytes_in = seen;
            on_read(stats);
        }
    }
    front.finish(reader.line_number(), out);
    flush();
    stats.lines_in = reader.line_number();
    stats.bytes_in = reader.bytes_read();
    return stats;
}

}  // namespace xlate5
