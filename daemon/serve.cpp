#include "daemon/serve.hpp"

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/systemd_sink.h>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include "daemon/ports.hpp"
#include "daemon/service.hpp"
#include "daemon/virtual_printer.hpp"
#include "translators/error.hpp"

namespace xlate5 {
namespace {

void setup_logging(const std::string& level) {
    // Under systemd (JOURNAL_STREAM is set), log straight to the journal with priorities.
    std::shared_ptr<spdlog::logger> logger;
    if (std::getenv("JOURNAL_STREAM")) logger = std::make_shared<spdlog::logger>("xlate5", std::make_shared<spdlog::sinks::systemd_sink_mt>());
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
    sopt.queue_lines = config.queue_lines;
    sopt.busy_interval = config.busy_interval;
    sopt.hold_seconds = config.hold_seconds;
    sopt.max_pending = config.max_pending;
    sopt.translator.input_name = "sender";
    sopt.translator.start_mode = config.mode;
    sopt.translator.extruder_letter = config.extruder_letter;
    a.service = std::make_unique<Service>(io, machine, sopt);
    Service& service = *a.service;

    // The firmware end. With the virtual printer, it sits on the master of a pseudo-terminal and
    // xlate5 opens the slave exactly as it would open a USB serial port.
    // Opening is also how the port comes back after it vanished (M999): for the virtual printer,
    // a fresh one is plugged in.
    SimOptions so = config.sim;
    so.axes.clear();
    for (const auto& j : machine.joints) so.axes += j.output;
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
            spdlog::info("firmware: the virtual printer ({}) on {}", so.reprap ? "RepRapFirmware-like" : "Marlin-like", device);
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
        service.add_sender(sl, "pty " + config.pty);
        spdlog::info("senders: open {} (-> {}) as the printer's serial port", config.pty, a.sender_pty->path());
    }
    if (!config.tcp.empty()) {
        const auto colon = config.tcp.rfind(':');
        if (colon == std::string::npos) throw IoError("sender.tcp: expected host:port, got '" + config.tcp + "'");
        boost::system::error_code ec;
        const auto address = asio::ip::make_address(config.tcp.substr(0, colon), ec);
        if (ec) throw IoError("sender.tcp: '" + config.tcp.substr(0, colon) + "' is not an IP address");
        if (!is_loopback(address) && !config.allow_remote)
            throw IoError("sender.tcp: " + config.tcp + " is not a loopback address; set allow_remote = true to bind it");
        const auto port = static_cast<unsigned short>(std::stoi(config.tcp.substr(colon + 1)));
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
                service.add_sender(std::make_shared<TcpLink>(std::move(socket), peer), peer);
                if (auto n = next.lock()) (*n)();
            });
        };
        (*a.accept_next)();
    }
}

int run_serve(const ServeConfig& config) {
    setup_logging(config.log_level);
    Machine machine;
    try {
        machine = load_configured_machine(config);
    } catch (const std::exception& e) {
        spdlog::error("machine: {}", e.what());
        return 3;
    }

    asio::io_context io;
    Assembly parts;
    try {
        assemble(io, config, machine, parts);
    } catch (const std::exception& e) {
        spdlog::error("{}", e.what());
        return 4;
    }
    Service& service = *parts.service;

    // SIGTERM/SIGINT: drain, then stop; a second one stops at once (between lines). SIGHUP:
    // reload the machine when idle.
    asio::signal_set signals(io, SIGINT, SIGTERM, SIGHUP);
    bool stopping = false;
    std::function<void()> wait_signal = [&] {
        signals.async_wait([&](boost::system::error_code ec, int sig) {
            if (ec) return;
            if (sig == SIGHUP) {
                if (config.source.empty()) {
                    spdlog::warn("SIGHUP: no configuration file to reload");
                } else {
                    const auto reload = [&] {
                        try {
                            const auto fresh = load_serve_config(config.source);
                            service.replace_machine(load_configured_machine(fresh));
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
            if (stopping) {
                spdlog::warn("second signal: stopping now, between lines");
                io.stop();
                return;
            }
            stopping = true;
            sd_notify(0, "STOPPING=1");
            spdlog::info("stopping: draining the queue (up to {} s)", config.drain_timeout);
            service.drain(config.drain_timeout, [&](const std::string& outcome) {
                spdlog::info("{}", outcome);
                io.stop();
            });
            wait_signal();
        });
    };
    wait_signal();
    sd_notify(0, "READY=1");
    io.run();
    const auto& st = service.stats();
    spdlog::info("lines from senders {}, lines to the firmware {}, refused {}", st.lines_in, st.lines_out, st.rejected);
    if (parts.sim)
        spdlog::info("virtual printer: executed {}, refused {}, dropped {}", parts.sim->stats().executed, parts.sim->stats().refused,
                     parts.sim->stats().dropped);
    return 0;
}

}  // namespace xlate5
