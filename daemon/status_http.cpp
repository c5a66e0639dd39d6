// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/status_http.hpp"

#include <cmath>
#include <cstdio>

#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <spdlog/spdlog.h>

#include "daemon/config.hpp"
#include "translators/error.hpp"

namespace xlate5 {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;

// JSON strings: quotes, backslashes and control characters escaped; bytes that are not UTF-8
// (a sender's line may hold any) become U+FFFD, so the document always parses.
void append_string(std::string& out, const std::string& s) {
    out += '"';
    const auto* p = reinterpret_cast<const unsigned char*>(s.data());
    const std::size_t n = s.size();
    for (std::size_t i = 0; i < n;) {
        const unsigned char c = p[i];
        if (c < 0x80) {
            if (c == '"') out += "\\\"";
            else if (c == '\\') out += "\\\\";
            else if (c < 0x20 || c == 0x7f) {
                char buf[8];
                std::snprintf(buf, sizeof buf, "\\u%04x", c);
                out += buf;
            } else out += char(c);
            ++i;
            continue;
        }
        // The length a lead byte announces, and the smallest code point of that length (no
        // overlong forms, no surrogates, nothing past U+10FFFF).
        std::size_t len = 0;
        std::uint32_t cp = 0, least = 0;
        if (c >= 0xc2 && c <= 0xdf) len = 2, cp = c & 0x1f, least = 0x80;
        else if (c >= 0xe0 && c <= 0xef) len = 3, cp = c & 0x0f, least = 0x800;
        else if (c >= 0xf0 && c <= 0xf4) len = 4, cp = c & 0x07, least = 0x10000;
        bool ok = len > 0 && i + len <= n;
        for (std::size_t k = 1; ok && k < len; ++k) {
            if ((p[i + k] & 0xc0) != 0x80) ok = false;
            else cp = (cp << 6) | (p[i + k] & 0x3f);
        }
        ok = ok && cp >= least && cp <= 0x10ffff && !(cp >= 0xd800 && cp <= 0xdfff);
        if (ok) {
            out.append(s, i, len);
            i += len;
        } else {
            out += "\xef\xbf\xbd";
            ++i;
        }
    }
    out += '"';
}

void append_number(std::string& out, double v) {
    if (!std::isfinite(v)) {
        out += "null";
        return;
    }
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.6f", v);
    std::string t = buf;
    // 12.500000 -> 12.5, 3.000000 -> 3: the figures the firmware would be sent, no trailing noise.
    if (t.find('.') != std::string::npos) {
        while (t.back() == '0') t.pop_back();
        if (t.back() == '.') t.pop_back();
    }
    if (t == "-0") t = "0";
    out += t;
}

struct Json {
    std::string out;
    bool first = true;
    void key(const char* k) {
        if (!first) out += ',';
        first = false;
        append_string(out, k);
        out += ':';
    }
    void str(const char* k, const std::string& v) { key(k), append_string(out, v); }
    void num(const char* k, double v) { key(k), append_number(out, v); }
    void whole(const char* k, std::uint64_t v) { key(k), out += std::to_string(v); }
    void open(const char* k) { key(k), out += '{', first = true; }
    void close() { out += '}', first = false; }
};

// The page: a table filled from /status.json every second by its script (served from here,
// so the page needs nothing from elsewhere, and its Content-Security-Policy allows nothing else).
const char* const kPage = R"HTML(<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>xlate5 status</title>
<style>
body { font: 15px/1.4 sans-serif; margin: 1.5em; color: #222; }
table { border-collapse: collapse; }
th { text-align: left; padding-right: 1.5em; font-weight: normal; color: #555; }
td { font-family: monospace; }
.note { color: #777; font-size: 13px; }
#error { color: #a00; }
</style>
</head>
<body>
<h1>xlate5 <span id="machine">…</span></h1>
<table>
<tr><th>state</th><td id="state">loading</td></tr>
<tr><th>firmware</th><td id="firmware"></td></tr>
<tr><th>printing</th><td id="line"></td></tr>
<tr><th>lines</th><td id="lines"></td></tr>
<tr><th>link busy</th><td id="busy"></td></tr>
<tr><th>joints</th><td id="joints"></td></tr>
<tr><th>tip</th><td id="tip"></td></tr>
<tr><th>tool axis</th><td id="axis"></td></tr>
<tr><th>last error</th><td id="error"></td></tr>
</table>
<p class="note">Read-only: nothing here changes the printer. This page has no authentication:
anyone who can reach it can read it. Data: <a href="/status.json">/status.json</a>.</p>
<script src="/status.js"></script>
</body>
</html>
)HTML";

const char* const kScript = R"JS(// xlate5's status page: /status.json into the table, once a second.
"use strict";
function set(id, text) { document.getElementById(id).textContent = text; }
function fixed(v) { return v === null ? "?" : v.toFixed(3); }
function show(s) {
  set("machine", s.machine);
  set("state", s.state + (s.stop_reason ? ": " + s.stop_reason : ""));
  const f = s.firmware;
  set("firmware", f.port + (f.state ? " (" + f.state + ")" : "") + ", queue " + f.queued + ", resends " + f.resends +
      ", timeouts " + f.timeouts);
  set("line", s.print.sender ? s.print.sender + ", line " + s.print.line : "nobody");
  set("lines", s.print.lines_from_senders + " from senders, " + s.print.lines_to_firmware + " to the firmware, " +
      s.print.refused + " refused");
  set("busy", f.link_busy_percent === null ? "?" : f.link_busy_percent.toFixed(1) + " %");
  const p = s.position;
  set("joints", p ? Object.keys(p.joints).map(k => k + " " + fixed(p.joints[k])).join("  ") : "");
  set("tip", p && p.tip ? p.tip.map(fixed).join(" ") : "");
  set("axis", p && p.axis ? p.axis.map(fixed).join(" ") : "");
  set("error", s.last_error);
}
function poll() {
  fetch("/status.json", {cache: "no-store"}).then(r => r.json()).then(show)
    .catch(e => set("state", "no answer from xlate5 (" + e + ")"));
}
poll();
setInterval(poll, 1000);
)JS";

}  // namespace

std::string status_json(const StatusSnapshot& s) {
    Json j;
    j.out = "{";
    j.str("xlate5", s.version);
    j.str("machine", s.machine);
    j.str("state", s.state);
    j.str("stop_reason", s.stop_reason);
    j.open("firmware");
    j.str("port", s.port);
    j.str("state", s.firmware_state);
    j.whole("queued", s.queued);
    j.whole("window", s.window);
    j.whole("sent", s.sent);
    j.whole("acked", s.acked);
    j.whole("resends", s.resends);
    j.whole("timeouts", s.timeouts);
    j.key("link_busy_percent");
    if (s.link_busy_percent) append_number(j.out, *s.link_busy_percent);
    else j.out += "null";
    j.close();
    j.open("print");
    j.str("sender", s.sender);
    j.key("line");
    if (s.line >= 0) j.out += std::to_string(s.line);
    else j.out += "null";
    j.whole("lines_from_senders", s.lines_from_senders);
    j.whole("lines_to_firmware", s.lines_to_firmware);
    j.whole("refused", s.refused);
    j.whole("cancelled", s.cancelled);
    j.whole("faults", s.faults);
    j.close();
    j.key("position");
    if (s.joints.empty() || s.joints.size() != s.joint_names.size()) {
        j.out += "null";
    } else {
        j.out += '{';
        j.first = true;
        j.open("joints");
        for (std::size_t i = 0; i < s.joints.size(); ++i) j.num(s.joint_names[i].c_str(), s.joints[i]);
        j.close();
        j.key("tip");
        if (s.pose) {
            const auto triple = [&](int from) {
                j.out += '[';
                for (int i = from; i < from + 3; ++i) {
                    if (i > from) j.out += ',';
                    append_number(j.out, (*s.pose)[std::size_t(i)]);
                }
                j.out += ']';
            };
            triple(0);
            j.key("axis");
            triple(3);
        } else {
            j.out += "null,\"axis\":null";
        }
        j.close();
    }
    j.str("last_error", s.last_error);
    j.str("authentication", "none");
    j.out += "}\n";
    return j.out;
}

struct StatusHttp::Impl : std::enable_shared_from_this<Impl> {
    Impl(asio::io_context& io, std::function<std::string()> json, StatusHttpOptions options)
        : acceptor(io), json(std::move(json)), options(options) {}
    asio::ip::tcp::acceptor acceptor;
    std::function<std::string()> json;
    StatusHttpOptions options;
    std::size_t open = 0;  // connections being served
    bool failing = false;

    void accept();
};

namespace {

struct Session : std::enable_shared_from_this<Session> {
    Session(asio::ip::tcp::socket socket, std::shared_ptr<StatusHttp::Impl> owner) : stream(std::move(socket)), owner(std::move(owner)) {
        ++this->owner->open;
    }
    ~Session() { --owner->open; }

    beast::tcp_stream stream;
    std::shared_ptr<StatusHttp::Impl> owner;
    beast::flat_buffer buffer;
    std::optional<http::request_parser<http::string_body>> parser;
    http::response<http::string_body> res;

    void read() {
        parser.emplace();
        parser->header_limit(static_cast<std::uint32_t>(owner->options.max_header_bytes));
        parser->body_limit(1024);  // no endpoint takes a body: a little is read only to answer 405
        stream.expires_after(std::chrono::milliseconds(static_cast<long>(owner->options.idle_seconds * 1000)));
        http::async_read(stream, buffer, *parser, [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
    }

    void reply(http::status status, std::string body, const char* type, bool keep_alive, unsigned version = 11) {
        res = {};
        res.version(version);
        res.result(status);
        res.set(http::field::server, "xlate5");
        res.set(http::field::content_type, type);
        res.set(http::field::cache_control, "no-store");
        res.set("X-Content-Type-Options", "nosniff");
        res.set("Content-Security-Policy", "default-src 'none'; script-src 'self'; connect-src 'self'; style-src 'unsafe-inline'");
        if (status == http::status::method_not_allowed) res.set(http::field::allow, "GET, HEAD");
        res.body() = std::move(body);
        res.keep_alive(keep_alive);
        res.prepare_payload();
    }

    void send(bool head_only) {
        auto self = shared_from_this();
        const bool close = !res.keep_alive();
        const auto done = [self, close](beast::error_code ec, std::size_t) {
            if (ec || close) return self->shut();
            self->read();
        };
        if (head_only) {
            // HEAD: the headers a GET would carry (Content-Length included), no body.
            http::response<http::empty_body> head{res.result(), res.version()};
            head.base() = res.base();
            auto h = std::make_shared<http::response<http::empty_body>>(std::move(head));
            http::async_write(stream, *h, [h, done](beast::error_code ec, std::size_t n) { done(ec, n); });
            return;
        }
        http::async_write(stream, res, done);
    }

    void shut() {
        beast::error_code ignored;
        stream.socket().shutdown(asio::ip::tcp::socket::shutdown_send, ignored);
        stream.close();
    }

    void on_read(beast::error_code ec) {
        if (ec == http::error::end_of_stream || ec == beast::error::timeout || ec == asio::error::operation_aborted) return shut();
        if (ec == http::error::header_limit) {
            reply(http::status::request_header_fields_too_large, "request headers longer than " +
                  std::to_string(owner->options.max_header_bytes) + " bytes\n", "text/plain; charset=utf-8", false);
            return send(false);
        }
        if (ec == http::error::body_limit) {
            reply(http::status::payload_too_large, "no endpoint takes a body\n", "text/plain; charset=utf-8", false);
            return send(false);
        }
        if (ec) {
            reply(http::status::bad_request, "not an HTTP/1.1 request\n", "text/plain; charset=utf-8", false);
            return send(false);
        }
        const auto& req = parser->get();
        const bool keep = req.keep_alive();
        const bool head = req.method() == http::verb::head;
        if (req.method() != http::verb::get && !head) {
            reply(http::status::method_not_allowed, "read-only: GET or HEAD only; nothing here changes the printer\n",
                  "text/plain; charset=utf-8", keep, req.version());
            return send(false);
        }
        std::string target(req.target());
        if (const auto q = target.find('?'); q != std::string::npos) target.resize(q);
        if (target == "/status.json") reply(http::status::ok, owner->json(), "application/json", keep, req.version());
        else if (target == "/" || target == "/index.html") reply(http::status::ok, kPage, "text/html; charset=utf-8", keep, req.version());
        else if (target == "/status.js") reply(http::status::ok, kScript, "text/javascript; charset=utf-8", keep, req.version());
        else reply(http::status::not_found, "not found: /, /status.json\n", "text/plain; charset=utf-8", keep, req.version());
        send(head);
    }
};

}  // namespace

void StatusHttp::Impl::accept() {
    acceptor.async_accept([self = shared_from_this()](boost::system::error_code ec, asio::ip::tcp::socket socket) {
        if (ec == asio::error::operation_aborted || !self->acceptor.is_open()) return;
        if (ec) {
            // Out of descriptors, or a connection gone before it was taken: again after a pause.
            if (!self->failing) spdlog::warn("status: http accept failed: {}; retrying every 0.2 s", ec.message());
            self->failing = true;
            auto t = std::make_shared<asio::steady_timer>(self->acceptor.get_executor(), std::chrono::milliseconds(200));
            t->async_wait([t, self](boost::system::error_code te) {
                if (!te) self->accept();
            });
            return;
        }
        self->failing = false;
        auto session = std::make_shared<Session>(std::move(socket), self);
        if (self->open > self->options.max_connections) {
            session->reply(http::status::service_unavailable,
                           "more than " + std::to_string(self->options.max_connections) + " connections open\n",
                           "text/plain; charset=utf-8", false);
            session->send(false);
        } else {
            session->read();
        }
        self->accept();
    });
}

StatusHttp::StatusHttp(asio::io_context& io, const std::string& host_port, bool allow_remote, std::function<std::string()> json,
                       StatusHttpOptions options)
    : impl_(std::make_shared<Impl>(io, std::move(json), options)) {
    TcpEndpoint endpoint;
    try {
        endpoint = parse_tcp_endpoint(host_port);
    } catch (const SettingError& e) {
        throw IoError(std::string("http: ") + e.what());
    }
    boost::system::error_code ec;
    const auto address = asio::ip::make_address(endpoint.host, ec);
    if (ec) throw IoError("http: '" + endpoint.host + "' is not an IP address");
    if (!address.is_loopback() && !allow_remote)
        throw IoError("http: " + host_port + " is not a loopback address, and the status page has no authentication; set allow_remote = "
                      "true to bind it");
    const asio::ip::tcp::endpoint ep(address, endpoint.port);
    auto& a = impl_->acceptor;
    a.open(ep.protocol());
    a.set_option(asio::socket_base::reuse_address(true));
    a.bind(ep, ec);
    if (ec) throw IoError("http: cannot bind " + host_port + ": " + ec.message());
    a.listen(static_cast<int>(options.max_connections));
    impl_->accept();
}

StatusHttp::~StatusHttp() {
    boost::system::error_code ignored;
    impl_->acceptor.close(ignored);
}

std::string StatusHttp::url() const {
    const auto ep = impl_->acceptor.local_endpoint();
    const std::string host = ep.address().is_v6() ? "[" + ep.address().to_string() + "]" : ep.address().to_string();
    return "http://" + host + ":" + std::to_string(ep.port()) + "/";
}

}  // namespace xlate5
