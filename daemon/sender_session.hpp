// SPDX-License-Identifier: GPL-3.0-or-later
// The sender side of the service, on a real link (stage: service, sender end; may call
// sender_protocol, link): xlate5 as the printer an OctoPrint-style sender believes it talks to.
// The protocol itself (Marlin's receive rules, the replies' words) is the I/O-free
// SenderProtocol; this adapter feeds it the link's lines, writes the lines it says to write and
// hands the service the commands it takes. The service answers ok once a command is in
// xlate5's queue.
#pragma once
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "daemon/lifetime.hpp"
#include "daemon/line_protocol.hpp"
#include "daemon/link.hpp"
#include "daemon/sender_protocol.hpp"

namespace xlate5 {

class SenderSession : public std::enable_shared_from_this<SenderSession> {
public:
    class Host {
    public:
        virtual ~Host() = default;
        // A command for the queue (comments kept: the translator reads them as the file would),
        // with the G/M code it starts with.
        // `numbered`: the line came with N and a checksum (OctoPrint numbers the lines of a print,
        // not what is typed in its terminal).
        virtual void sender_command(SenderSession& s, std::string_view command, proto::Code code, std::uint64_t line_no,
                                    bool numbered) = 0;
        // M112, M108, M410: to the firmware at once, ahead of the queue.
        virtual void sender_emergency(SenderSession& s, std::string_view command) = 0;
        // M115's answer, without the final ok.
        virtual std::string sender_m115() = 0;
        virtual void sender_gone(SenderSession& s) = 0;   // the link closed (TCP): the session ends
        virtual void sender_left(SenderSession& s) = 0;   // the sender closed the pseudo-terminal: it may come back
        virtual void sender_reset(SenderSession& s) = 0;  // M110: the sender starts numbering again (a new print)
        // A line the session cannot take whole (longer than the link's max_line): refused in
        // its turn, as a line the translator refuses (a numbered one ends the print).
        virtual void sender_refused(SenderSession& s, std::string_view command, std::uint64_t line_no, bool numbered,
                                    std::string cause) = 0;
    };

    SenderSession(std::shared_ptr<Link> link, Host& host, std::string name);
    ~SenderSession();
    void start();
    void close();
    // The service's answers (SenderProtocol's events of the same names).
    void send_line(std::string_view line) { proto_.say(line); after_event(); }  // one reply line
    void ok(std::string_view payload = {}) { proto_.ok(payload); after_event(); }
    void busy() { proto_.busy(); after_event(); }
    void refused(std::string_view quoted, bool numbered) { proto_.refused(quoted, numbered); after_event(); }
    void not_run(std::string_view command, std::string_view reason, bool healthy) {
        proto_.not_run(command, reason, healthy);
        after_event();
    }
    void turned_away(std::string_view why) { proto_.turned_away(why); after_event(); }
    const std::string& name() const { return name_; }
    std::int64_t last_line() const { return proto_.last_line(); }
    bool open() const { return link_->open(); }
    void pause_reading() { link_->pause_reading(); }
    void resume_reading() { link_->resume_reading(); }
    std::size_t in_service = 0;  // its lines the service holds, not yet translated (kept by the service)
    bool tcp = false;            // a TCP connection (bounded in number, closed when idle)
    std::chrono::steady_clock::time_point last_heard() const { return last_heard_; }
    // Replies not yet written that make a sender "not reading": the session is closed.
    static constexpr std::size_t kMaxUnreadBytes = std::size_t(1) << 20;

private:
    void after_event();  // carry out the protocol's actions
    void write(const std::string& line);

    std::shared_ptr<Link> link_;
    Host& host_;
    std::string name_;
    SenderProtocol proto_;
    std::chrono::steady_clock::time_point last_heard_ = std::chrono::steady_clock::now();
    Lifetime lifetime_;
};

}  // namespace xlate5
