// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/serve.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <fcntl.h>
#include <fstream>
#include <unistd.h>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/systemd_sink.h>
#include <spdlog/spdlog.h>

#include "daemon/log_policy.hpp"
#include "daemon/notify.hpp"
#include "daemon/ports.hpp"
#include "daemon/service.hpp"
#include "daemon/status_http.hpp"
#include "daemon/virtual_printer.hpp"
#include "translators/error.hpp"
#include "translators/inputs/line_reader.hpp"

namespace xlate5 {
namespace {

void setup_logging(const std::string& level) {
    // Under systemd (standard error is the journal's stream), log straight to the journal with
    // priorities; anywhere else (JOURNAL_STREAM inherited, stderr redirected), to standard error.
    std::shared_ptr<spdlog::logger> logger;
    if (journal_stream_is(STDERR_FILENO, std::getenv("JOURNAL_STREAM"))) logger = std::make_shared<spdlog::logger>("xlate5", std::make_shared<spdlog::sinks::systemd_sink_mt>());
    else logger = spdlog::stderr_color_mt("xlate5");
    spdlog::set_default_logger(logger);
    spdlog::set_level(spdlog::level::from_str(level));
}

Machine load_configured_machine(const ServeConfig& c) {
    Machine m = load_machine(c.machine);
    if (!c.compensation.empty()) load_compensation_file(c.compensation, m);
    if (c.tolerance > 0) m.motion.tolerance = c.tolerance;
    return m;
}

bool is_loopback(const asio::ip::address& a) { return a.is_loopback(); }

}  // namespace

int run_ports() {
    const auto ports = list_ports();
    if (ports.empty()) {
        std::printf("no serial ports found\n");
        return 0;
    }
    for (const auto& p : ports) {
        std::printf("%-20s %-9s", p.path.c_str(), p.transport.c_str());
        if (p.usb_vid >= 0) std::printf(" %04x:%04x", p.usb_vid, p.usb_pid);
        std::printf(" %s", p.description.c_str());
        if (!p.manufacturer.empty() || !p.product.empty()) std::printf(" (%s %s)", p.manufacturer.c_str(), p.product.c_str());
        if (!p.serial.empty()) std::printf(" serial %s", p.serial.c_str());
        std::printf("\n");
    }
    return 0;
}

void assemble(asio::io_context& io, const ServeConfig& config, const Machine& machine, Assembly& a) {
    ServiceOptions sopt;
    static_cast<SenderLimits&>(sopt) = config;  // the sender.* settings, as they are
    sopt.translator.input_name = "sender";
    sopt.translator.start_mode = config.mode;
    sopt.translator.extruder_letter = config.extruder_letter;
    if (config.port.empty()) throw IoError("firmware.port: not set (a serial device, or \"sim\" for the built-in virtual printer)");
    // Klipper drops the words of an extra axis it was not told about, and its G92 reads only
    // X Y Z E: only the Klipper dialect's output (MANUAL_STEPPER registration and SET_POSITION)
    // runs as translated there.
    if (config.firmware.klipper && machine.dialect.firmware != FirmwareDialect::Klipper)
        for (const auto& j : machine.joints)
            if (j.output != 'X' && j.output != 'Y' && j.output != 'Z' && !j.absent)
                throw IoError("firmware.flavor: klipper, but machine " + machine.name + " writes its " + std::string(1, j.output) +
                              " words in another dialect (its [firmware] dialect): Klipper would drop them or, after a G92, zero X Y Z E; "
                              "set dialect = \"klipper\" in the machine file (docs/firmware.md, Klipper)");
    a.service = std::make_unique<Service>(io, machine, sopt);
    Service& service = *a.service;

    // The firmware end. With the virtual printer, it sits on the master of a pseudo-terminal and
    // xlate5 opens the slave exactly as it would open a USB serial port.
    // Opening is also how the port comes back after it vanished (M999): for the virtual printer,
    // a fresh one is plugged in.
    SimOptions so = config.sim;
    so.axes.clear();
    for (const auto& j : machine.joints) so.axes += j.output;
    if (so.start.empty()) {
        // The virtual machine powers up where xlate5's offline translation starts: at home.
        so.start = machine.home_joints();
        machine.compensation.apply(so.start);
    }
    auto open = [&io, &a, config, so]() -> std::shared_ptr<Link> {
        std::string device = config.port;
        if (config.port == "sim") {
            a.sim_pty = std::make_unique<Pty>();
            device = a.sim_pty->path();
        }
        a.port = std::make_unique<SerialPort>(device, config.baud);
        auto link = std::make_shared<DescriptorLink>(asio::posix::stream_descriptor(io, a.port->release_fd()), device);
        if (config.port == "sim") {
            a.sim = std::make_shared<VirtualPrinter>(io, a.sim_pty->release_master(), so);
            a.sim->start();
            spdlog::info("firmware: the virtual printer ({}) on {}", so.reprap ? "RepRapFirmware-like" : so.klipper ? "Klipper-like" : "Marlin-like", device);
        } else {
            spdlog::info("firmware: {} at {} baud", device, config.baud);
        }
        return link;
    };
    service.attach_firmware(open(), config.firmware);
    service.set_reopen(open);

    // Sender ends.
    if (!config.pty.empty()) {
        a.sender_pty = std::make_unique<Pty>(config.pty, config.pty_group);
        auto sl = std::make_shared<DescriptorLink>(asio::posix::stream_descriptor(io, a.sender_pty->release_master()), a.sender_pty->link());
        sl->eio_is_transient = true;  // a sender closing the port is not the end of the service
        sl->on_presence = [name = "pty " + config.pty](bool present) {
            if (present) spdlog::info("sender connected: {}", name);
            else spdlog::info("sender closed {}", name.substr(4));
        };
        service.add_sender(sl, "pty " + config.pty);
        spdlog::info("senders: open {} (-> {}) as the printer's serial port", config.pty, a.sender_pty->path());
    }
    if (!config.tcp.empty()) {
        TcpEndpoint endpoint;
        try {
            endpoint = parse_tcp_endpoint(config.tcp);
        } catch (const SettingError& e) {
            throw IoError(std::string("sender.tcp: ") + e.what());
        }
        boost::system::error_code ec;
        const auto address = asio::ip::make_address(endpoint.host, ec);
        if (ec) throw IoError("sender.tcp: '" + endpoint.host + "' is not an IP address");
        if (!is_loopback(address) && !config.allow_remote)
            throw IoError("sender.tcp: " + config.tcp + " is not a loopback address; set allow_remote = true to bind it");
        const auto port = endpoint.port;
        a.acceptor.emplace(io);
        const asio::ip::tcp::endpoint ep(address, port);
        a.acceptor->open(ep.protocol());
        a.acceptor->set_option(asio::socket_base::reuse_address(true));
        a.acceptor->bind(ep, ec);
        if (ec) throw IoError("sender.tcp: cannot bind " + config.tcp + ": " + ec.message());
        a.acceptor->listen();
        spdlog::info("senders: tcp {}:{}", address.to_string(), a.acceptor->local_endpoint().port());
        a.accept_next = std::make_shared<std::function<void()>>();
        auto* acceptor = &*a.acceptor;
        std::weak_ptr<std::function<void()>> next = a.accept_next;
        auto failing = std::make_shared<bool>(false);
        *a.accept_next = [acceptor, &service, next, failing] {
            acceptor->async_accept([acceptor, &service, next, failing](boost::system::error_code e, asio::ip::tcp::socket socket) {
                if (e == asio::error::operation_aborted || !acceptor->is_open()) return;
                if (e) {
                    // Out of file descriptors (EMFILE, ENFILE) or a connection gone before it was
                    // taken: try again after a pause (a timer, not a busy loop), never stop for good.
                    if (!*failing) spdlog::warn("senders: tcp accept failed: {}; retrying every 0.2 s", e.message());
                    *failing = true;
                    auto t = std::make_shared<asio::steady_timer>(acceptor->get_executor(), std::chrono::milliseconds(200));
                    t->async_wait([t, next](boost::system::error_code te) {
                        if (auto n = next.lock(); n && !te) (*n)();
                    });
                    return;
                }
                if (*failing) spdlog::info("senders: tcp accepting again");
                *failing = false;
                socket.set_option(asio::ip::tcp::no_delay(true));
                boost::system::error_code pe;
                const auto rep = socket.remote_endpoint(pe);
                const auto peer = "tcp " + rep.address().to_string() + ":" + std::to_string(rep.port());
                spdlog::info("sender connected: {}", peer);
                service.add_sender(std::make_shared<TcpLink>(std::move(socket), peer), peer, true);
                if (auto n = next.lock()) (*n)();
            });
        };
        (*a.accept_next)();
    }
}

namespace {

// The firmware end as the start log and `serve --check` describe it.
std::string link_summary(const ServeConfig& c) {
    const auto& f = c.firmware;
    std::string port = c.port.empty() ? "no port set" : c.port == "sim" ? std::string("the built-in virtual printer (") + (c.sim.reprap ? "RepRapFirmware" : c.sim.klipper ? "Klipper" : "Marlin") + "-like)" : c.port;
    if (f.klipper)
        return port + ", klipper; " + std::to_string(f.window > 0 ? f.window : klipper::kWindow) + " lines and " +
               std::to_string(klipper::kReadBytes - 1) + " bytes in flight at most (one of klippy's reads), plain lines";
    const std::string window = f.reprap ? "1 line in flight (RepRapFirmware drops a bad line without a word)"
                               : f.window > 0 ? std::to_string(f.window) + " lines in flight"
                                              : "2 lines in flight (more when ADVANCED_OK reports a larger buffer)";
    return port + ", " + (f.reprap ? "reprap" : "marlin") + ", " + std::to_string(c.baud) + " baud; " + window + ", at most " +
           std::to_string(f.rx_bytes) + " bytes in flight (receive buffer), lines up to " + std::to_string(f.max_line) + " bytes";
}

std::string seconds_text(double s) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f s", s);
    return buf;
}

// The one-line state systemd shows (`systemctl status`): lines, queue, resends.
std::string status_line(Service& service, const std::string& waiting_for) {
    if (!waiting_for.empty()) return "STATUS=waiting for " + waiting_for + " to appear";
    const auto& st = service.stats();
    std::string s = "STATUS=";
    if (service.stopped()) s += "stopped: " + service.stop_reason() + "; ";
    else s += std::string(service.activity()) + "; ";
    s += std::to_string(st.lines_in) + " lines from senders, " + std::to_string(st.lines_out) + " to the firmware";
    if (auto* fw = service.firmware())
        s += ", queue " + std::to_string(fw->queued()) + ", resends " + std::to_string(fw->stats().resend_requests) + ", timeouts " +
             std::to_string(fw->stats().timeouts);
    return s;
}

}  // namespace

int run_serve(const ServeConfig& config) {
    setup_logging(config.log_level);
    Machine machine;
    try {
        machine = load_configured_machine(config);
    } catch (const std::exception& e) {
        spdlog::error("machine: {}", e.what());
        return 3;
    }
    const auto started = std::chrono::steady_clock::now();
    spdlog::info("xlate5 {} serve: machine {}; firmware {}", XLATE5_VERSION_STRING, machine.name, link_summary(config));

    asio::io_context io;
    Assembly parts;
    int exit_code = 0;
    bool stopping = false;
    // A printer switched off is a port that is not there yet: wait for it (and say so once)
    // rather than exit and be restarted by systemd every few seconds. The senders' endpoints
    // open with the firmware's, so a sender finds the printer when the printer is there.
    std::string waiting_for;
    asio::steady_timer port_timer(io), status_timer(io);
    const auto start = [&] {
        try {
            assemble(io, config, machine, parts);
        } catch (const std::exception& e) {
            spdlog::error("{}", e.what());
            exit_code = 4;
            io.stop();
        }
    };
    std::function<void()> wait_port = [&] {
        if (::access(config.port.c_str(), R_OK | W_OK) == 0) {
            if (!waiting_for.empty()) spdlog::info("firmware: {} is there", config.port);
            waiting_for.clear();
            start();
            return;
        }
        if (waiting_for.empty()) {
            spdlog::warn("firmware: waiting for {} to appear ({}); senders can connect once it is there", config.port, std::strerror(errno));
            waiting_for = config.port;
            notify_systemd("STATUS=waiting for " + waiting_for + " to appear");
        }
        port_timer.expires_after(std::chrono::milliseconds(250));
        port_timer.async_wait([&](boost::system::error_code ec) {
            if (!ec && !stopping) wait_port();
        });
    };

    // SIGTERM/SIGINT: drain, then stop; a second one stops at once (between lines). SIGHUP:
    // reload the machine when idle.
    asio::signal_set signals(io, SIGINT, SIGTERM, SIGHUP);
    std::function<void()> wait_signal = [&] {
        signals.async_wait([&](boost::system::error_code ec, int sig) {
            if (ec) return;
            if (sig == SIGHUP) {
                if (config.source.empty()) {
                    spdlog::warn("SIGHUP: no configuration file to reload");
                } else if (!parts.service) {
                    spdlog::warn("SIGHUP: the firmware's port is not there yet; nothing to reload");
                } else {
                    Service& service = *parts.service;
                    const auto reload = [&] {
                        try {
                            const auto fresh = load_serve_config(config.source);
                            parts.service->replace_machine(load_configured_machine(fresh));
                            spdlog::info("SIGHUP: reloaded {} (machine {}); port and endpoint changes need a restart", config.source,
                                         fresh.machine);
                        } catch (const std::exception& e) {
                            spdlog::error("SIGHUP: {} (keeping the running configuration)", e.what());
                        }
                    };
                    if (!service.idle()) spdlog::warn("SIGHUP: a print is running; the configuration is reloaded once it is idle");
                    service.when_idle(reload);
                }
                wait_signal();
                return;
            }
            if (stopping || !parts.service) {
                if (stopping && parts.service)
                    spdlog::warn("second signal: stopping now, between lines: {} acknowledged lines of the senders not executed{}",
                                 parts.service->acknowledged_not_run(),
                                 parts.service->holding() ? ", and the moves the look-back still held" : "");
                else if (stopping) spdlog::warn("second signal: stopping now");
                stopping = true;
                io.stop();
                return;
            }
            stopping = true;
            notify_systemd("STOPPING=1");
            spdlog::info("stopping: draining the queue (up to {} s)", config.drain_timeout);
            parts.service->drain(config.drain_timeout, [&](const std::string& outcome) {
                spdlog::info("{}", outcome);
                io.stop();
            });
            wait_signal();
        });
    };
    wait_signal();

    // The read-only status page (--http): what the service is doing, for a person or an
    // integration that does not read the journal. The busy share of the firmware's wire is
    // sampled by the status tick below.
    std::optional<double> link_busy;
    std::unique_ptr<StatusHttp> status_http;
    if (!config.http.empty()) {
        const auto snapshot = [&] {
            StatusSnapshot s;
            s.version = XLATE5_VERSION_STRING;
            // The service's machine once there is one: SIGHUP may have reloaded another.
            const Machine& m = parts.service ? parts.service->machine() : machine;
            s.machine = m.name;
            s.port = config.port;
            for (const auto& j : m.joints) s.joint_names.emplace_back(1, j.output);
            if (!parts.service) {
                s.state = waiting_for.empty() ? "starting" : "waiting for port";
                return status_json(s);
            }
            Service& service = *parts.service;
            s.state = service.activity();
            s.stop_reason = service.stop_reason();
            if (auto* fw = service.firmware()) {
                using State = FirmwareLink::State;
                const auto st = fw->state();
                s.firmware_state = st == State::Booting ? "booting" : st == State::Greeting ? "greeting" : st == State::Ready ? "ready" : "faulted";
                s.queued = fw->queued();
                s.window = std::uint64_t(std::max(fw->window(), 0));
                s.sent = fw->stats().sent;
                s.acked = fw->stats().acked;
                s.resends = fw->stats().resend_requests;
                s.timeouts = fw->stats().timeouts;
            }
            s.link_busy_percent = link_busy;
            const auto& st = service.stats();
            s.lines_from_senders = st.lines_in;
            s.lines_to_firmware = st.lines_out;
            s.refused = st.rejected;
            s.cancelled = st.cancelled;
            s.faults = st.faults;
            const auto v = service.view();
            s.sender = v.sender;
            s.line = v.line;
            s.joints = v.joints;
            s.pose = std::array<double, 6>{v.pose.tip.x(), v.pose.tip.y(), v.pose.tip.z(), v.pose.axis.x(), v.pose.axis.y(), v.pose.axis.z()};
            s.last_error = service.last_error();
            return status_json(s);
        };
        try {
            status_http = std::make_unique<StatusHttp>(io, config.http, config.allow_remote, snapshot);
        } catch (const std::exception& e) {
            spdlog::error("{}", e.what());
            return 4;
        }
        spdlog::info("status: {} and {}status.json, read-only, WITHOUT authentication: anyone who can reach it reads the printer's state",
                     status_http->url(), status_http->url());
    }

    if (config.port == "sim") start();
    else wait_port();
    // STATUS= for systemctl status, when it changed, every 2 s.
    std::string last_status;
    // The firmware wire's busy share: bytes written over the last tick against what the line
    // carries at its baud rate (10 bits a byte); the virtual printer's own speed when it has one.
    const double wire_bytes_per_second = (config.port == "sim" ? config.sim.baud : config.baud) / 10.0;
    std::uint64_t last_bytes = 0;
    auto last_sample = std::chrono::steady_clock::now();
    std::function<void()> tick = [&] {
        if (parts.service) {
            auto st = status_line(*parts.service, waiting_for);
            if (st != last_status) notify_systemd(st), last_status = std::move(st);
            if (auto* fw = parts.service->firmware(); fw && wire_bytes_per_second > 0) {
                const auto now = std::chrono::steady_clock::now();
                const auto bytes = fw->link().bytes_written();
                const double dt = std::chrono::duration<double>(now - last_sample).count();
                if (bytes >= last_bytes && dt > 0) link_busy = std::min(100.0, 100.0 * double(bytes - last_bytes) / (wire_bytes_per_second * dt));
                last_bytes = bytes;
                last_sample = now;
            }
        }
        status_timer.expires_after(std::chrono::seconds(2));
        status_timer.async_wait([&](boost::system::error_code ec) {
            if (!ec) tick();
        });
    };
    tick();
    notify_systemd(waiting_for.empty() ? "READY=1" : "READY=1\nSTATUS=waiting for " + waiting_for + " to appear");
    io.run();

    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    if (!parts.service) {
        spdlog::info("stopped after {} without a firmware (its port never appeared)", seconds_text(seconds));
        return exit_code;
    }
    const auto& st = parts.service->stats();
    std::string firmware = "no firmware";
    if (auto* fw = parts.service->firmware()) {
        const auto& f = fw->stats();
        firmware = std::to_string(f.acked) + " acknowledged, " + std::to_string(f.resend_requests) + " resends, " + std::to_string(f.timeouts) +
                   " timeouts, " + std::to_string(f.probes) + " probes";
    }
    spdlog::info("served {}: {} lines from senders, {} to the firmware, {} refused, {} prints cancelled, {} firmware faults; firmware: {}",
                 seconds_text(seconds), st.lines_in, st.lines_out, st.rejected, st.cancelled, st.faults, firmware);
    if (parts.sim)
        spdlog::info("virtual printer: executed {}, refused {}, dropped {}", parts.sim->stats().executed, parts.sim->stats().refused,
                     parts.sim->stats().dropped);
    return exit_code;
}

int run_serve_check(const ServeConfig& config, const std::string& path) {
    Machine machine;
    try {
        machine = load_configured_machine(config);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "xlate5: machine: %s\n", e.what());
        return 3;
    }
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        std::fprintf(stderr, "xlate5: %s: cannot read: %s\n", path.c_str(), std::strerror(errno));
        return 4;
    }
    // Serve's line bound (a longer line cancels a numbered print there, so reading stops), and
    // the check's own bounds on what it holds (docs/limits.md).
    std::vector<std::string> lines;
    std::optional<ServePlan::Point> overlong;
    const std::string overlong_cause = "longer than " + std::to_string(Link::kMaxLine) + " bytes (the line-length bound)";
    try {
        LineReader reader(fd, path, Link::kMaxLine);
        std::string_view l;
        while (reader.next(l)) {
            if (reader.bytes_consumed() > kMaxCheckBytes || reader.line_number() > kMaxCheckLines) {
                ::close(fd);
                std::fprintf(stderr,
                             "%s:%llu:1: serve --check holds the file and its translation in memory: at most %llu bytes and %llu lines "
                             "(docs/limits.md; serve itself streams): check the file in parts, or translate it offline\n",
                             path.c_str(), static_cast<unsigned long long>(reader.line_number()),
                             static_cast<unsigned long long>(kMaxCheckBytes), static_cast<unsigned long long>(kMaxCheckLines));
                return 1;
            }
            if (l.size() > Link::kMaxLine) {  // the reader holds a line longer than its bound when it has it whole
                overlong = ServePlan::Point{reader.line_number(), "(a line longer than " + std::to_string(Link::kMaxLine) + " bytes)"};
                break;
            }
            if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
            lines.emplace_back(l);
        }
    } catch (const InputError& e) {
        // Past Link::kMaxLine: what the service's sender session refuses.
        overlong = ServePlan::Point{e.line(), "(a line longer than " + std::to_string(Link::kMaxLine) + " bytes)"};
    } catch (const IoError& e) {
        ::close(fd);
        std::fprintf(stderr, "xlate5: %s\n", e.what());
        return 4;
    }
    ::close(fd);
    TranslatorOptions topt;
    topt.start_mode = config.mode;
    topt.extruder_letter = config.extruder_letter;
    {
        // The translation's size first, line by line, before three copies of it are kept.
        const Kinematics kin(machine);
        TranslatorOptions o = topt;
        o.input_name = path;
        Translator t(kin, o);
        t.set_lookback(Translator::kDefaultLookback);
        std::uint64_t out_bytes = 0, n = 0;
        std::string text;
        try {
            for (const auto& l : lines) {
                text.clear();
                t.feed(l, ++n, text);
                out_bytes += text.size();
                if (out_bytes > kMaxCheckOutputBytes) {
                    std::fprintf(stderr,
                                 "%s:%llu:1: serve --check holds the translation in memory: at most %llu bytes of it (docs/limits.md; "
                                 "serve itself streams): check the file in parts, or translate it offline\n",
                                 path.c_str(), static_cast<unsigned long long>(n), static_cast<unsigned long long>(kMaxCheckOutputBytes));
                    return 1;
                }
            }
        } catch (const InputError&) {
            // Both translations below stop here and say so.
        }
    }
    auto plan = plan_as_serve(machine, lines, topt, config.firmware);
    if (overlong && !plan.cancel) {
        plan.cancel = *overlong;
        plan.cause = overlong_cause;
    }
    std::optional<std::string> offline_error;
    std::vector<std::string> offline;
    try {
        offline = firmware_commands(machine, lines, topt);
    } catch (const InputError& e) {
        offline_error = e.what();
    }

    std::printf("serve --check %s (machine %s)\n", path.c_str(), machine.name.c_str());
    std::printf("the firmware: %s%s\n", link_summary(config).c_str(),
                config.port.empty() ? " (serve would not start: give --port DEVICE, --printer sim or [firmware] port)" : "");
    std::printf("senders: %s%s; the queue holds %zu translated lines; a sender may write %zu lines ahead\n",
                config.pty.empty() ? "no pseudo-terminal" : ("pseudo-terminal " + config.pty).c_str(),
                config.tcp.empty() ? "" : (", tcp " + config.tcp).c_str(), config.queue_lines, config.max_pending);
    std::printf("look-back: as offline (%zu lines), but held output goes to the firmware early before every wait or report,\n"
                "  after a pause of %g s in the sender's stream, and when the service drains\n",
                Translator::kDefaultLookback, config.hold_seconds);
    const auto quote = [](const ServePlan::Point& p) {
        std::string t = p.text.size() > 60 ? p.text.substr(0, 57) + "..." : p.text;
        return "line " + std::to_string(p.line) + " '" + t + "'";
    };
    const auto list = [&](const char* what, const std::vector<ServePlan::Point>& points) {
        std::printf("%s: %zu\n", what, points.size());
        constexpr std::size_t kShown = 10;
        for (std::size_t i = 0; i < points.size() && i < kShown; ++i) std::printf("  %s\n", quote(points[i]).c_str());
        if (points.size() > kShown) std::printf("  ... and %zu more\n", points.size() - kShown);
    };
    std::printf("%zu input lines -> %zu firmware lines\n", lines.size(), plan.commands.size());
    list("held output released before a wait or report (offline keeps holding it)", plan.releases);
    list("lines whose output is split or shortened for the firmware's line buffer", plan.split);
    bool same = !plan.cancel && !offline_error && plan.translated == offline;
    if (plan.cancel) {
        std::printf("serve would cancel the print at %s: %s\n", quote(*plan.cancel).c_str(), plan.cause.c_str());
        if (plan.too_long) std::printf("  no split fits the firmware's %zu-byte lines (F alone, then the rest): raise max_line if it takes longer ones\n",
                                       config.firmware.max_line);
        else if (overlong && plan.cancel->line == overlong->line)
            std::printf("  a sender's line is at most %zu bytes; nothing after it was read\n", Link::kMaxLine);
        else if (!offline_error)
            std::printf("  offline translation keeps it: an unwind it finds by look-back would reach back across a release above\n");
    }
    if (offline_error) std::printf("offline translation refuses the file: %s\n", offline_error->c_str());
    if (!plan.cancel && !offline_error && !same) {
        const auto m = std::mismatch(plan.translated.begin(), plan.translated.end(), offline.begin(), offline.end());
        std::printf("serve's joint moves differ from offline from firmware line %zu: '%s' (offline: '%s')\n",
                    std::size_t(m.first - plan.translated.begin()) + 1, m.first != plan.translated.end() ? m.first->c_str() : "<end>",
                    m.second != offline.end() ? m.second->c_str() : "<end>");
    }
    if (same) std::printf("serve prints the same joint moves as offline translation\n");
    return same ? 0 : 1;
}

}  // namespace xlate5
