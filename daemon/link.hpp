// SPDX-License-Identifier: GPL-3.0-or-later
// A line-oriented, full-duplex byte link over any Asio stream (a serial port or pseudo-terminal
// descriptor, a TCP socket): lines in through a callback, text out through an ordered write
// queue. Both sides of the service and the virtual printer talk through it. Stage: the
// service's transport; may call Asio only.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include <utility>  // before Asio: Boost 1.74's awaitable.hpp uses std::exchange without it

#include <boost/asio.hpp>

namespace xlate5 {

namespace asio = boost::asio;

class Link : public std::enable_shared_from_this<Link> {
public:
    using LineHandler = std::function<void(std::string_view line)>;
    // Called once when the link ends: `why` is empty for an orderly close by this side.
    using CloseHandler = std::function<void(const std::string& why)>;

    virtual ~Link() = default;
    // Starts reading. Lines end at '\n' (a '\r' before it is dropped); a line longer than
    // `max_line` bytes is cut there, as a firmware's buffer would, the rest up to its '\n'
    // dropped, and line_cut() is true while its first `max_line` bytes are handled.
    void start(LineHandler on_line, CloseHandler on_close);
    // Queues text (whole lines, with their '\n') to be written in order.
    void send(std::string_view text);
    void close();
    bool open() const { return open_; }
    // Back-pressure: no more reads until resumed (lines of the chunk already read are still
    // delivered), so a peer that writes without waiting cannot grow memory here.
    void pause_reading() { paused_ = true; }
    void resume_reading();
    // Called when the other end goes away for now (a pseudo-terminal whose sender closed it).
    void on_hangup(std::function<void()> f) { on_hangup_ = std::move(f); }
    std::size_t unsent_bytes() const { return out_.size() + writing_.size(); }
    std::uint64_t bytes_written() const { return bytes_written_; }  // all bytes the stream took
    const std::string& name() const { return name_; }
    asio::any_io_executor stream_executor() { return executor(); }
    // A sender's line past this is refused whole (docs/limits.md); `serve --check` applies it too.
    static constexpr std::size_t kMaxLine = 1 << 16;
    std::size_t max_line = kMaxLine;
    bool line_cut() const { return cut_; }
    // Raw bytes: called with each read's byte count before its lines are handed on (the virtual
    // printer times its wire by the byte, so a line sent in two parts crosses in two parts).
    std::function<void(std::size_t)> on_bytes;
    // Someone at the other end: true with the first bytes read (at first, or after a hang-up),
    // false at a hang-up after that. A pseudo-terminal cannot tell that its slave was opened
    // until bytes come, so "connected" is when the sender first writes.
    std::function<void(bool present)> on_presence;
    // While a line is handled: the count of bytes read up to and including its '\n'.
    std::uint64_t line_end() const { return line_end_; }

protected:
    explicit Link(std::string name) : name_(std::move(name)) {}
    virtual void read_some(asio::mutable_buffer buffer, std::function<void(boost::system::error_code, std::size_t)> done) = 0;
    virtual void write_all(asio::const_buffer buffer, std::function<void(boost::system::error_code, std::size_t)> done) = 0;
    virtual void close_stream() = 0;
    // A read error that means "nobody on the other end right now" rather than the end of the
    // link (a pseudo-terminal whose sender closed it): reading is retried after a pause.
    virtual bool transient(const boost::system::error_code&) const { return false; }
    virtual asio::any_io_executor executor() = 0;

private:
    void read();
    void write();
    void finish(const std::string& why);

    std::string name_;
    LineHandler on_line_;
    CloseHandler on_close_;
    std::array<char, 4096> buffer_{};
    std::string partial_;
    std::string out_, writing_;
    bool writing_now_ = false;
    bool open_ = true;
    bool overlong_ = false;
    bool cut_ = false;
    std::uint64_t bytes_read_ = 0, line_end_ = 0, bytes_written_ = 0;
    bool paused_ = false, reading_ = false, hung_up_ = false, present_ = false;
    std::function<void()> on_hangup_;
    std::unique_ptr<asio::steady_timer> retry_;
};

// The Link over a concrete Asio stream.
template <class Stream>
class StreamLink final : public Link {
public:
    StreamLink(Stream stream, std::string name) : Link(std::move(name)), stream_(std::move(stream)) {}
    Stream& stream() { return stream_; }
    // For pseudo-terminal masters: EIO means the sender has closed its end, not that the link is gone.
    bool eio_is_transient = false;

protected:
    void read_some(asio::mutable_buffer b, std::function<void(boost::system::error_code, std::size_t)> done) override {
        stream_.async_read_some(b, std::move(done));
    }
    void write_all(asio::const_buffer b, std::function<void(boost::system::error_code, std::size_t)> done) override {
        asio::async_write(stream_, b, std::move(done));
    }
    void close_stream() override {
        boost::system::error_code ignored;
        stream_.close(ignored);
    }
    bool transient(const boost::system::error_code& ec) const override {
        return eio_is_transient && ec == boost::system::errc::io_error;
    }
    asio::any_io_executor executor() override { return stream_.get_executor(); }

private:
    Stream stream_;
};

using DescriptorLink = StreamLink<asio::posix::stream_descriptor>;
using TcpLink = StreamLink<asio::ip::tcp::socket>;

}  // namespace xlate5
