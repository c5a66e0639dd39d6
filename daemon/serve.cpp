#include "daemon/serve.hpp"

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
    ServiceOptions sopt;
    sopt.queue_lines = config.queue_lines;
    sopt.translator.input_name = "sender";
    Service service(io, machine, sopt);

    // The firmware end. With the virtual printer, it sits on the master of a pseudo-terminal and
    // xlate5 opens the slave exactly as it would open a USB serial port.
    std::unique_ptr<Pty> sim_pty;
    std::shared_ptr<VirtualPrinter> sim;
    std::string device = config.port;
    std::unique_ptr<SerialPort> port;
    try {
        if (config.port == "sim") {
            sim_pty = std::make_unique<Pty>();
            device = sim_pty->path();
        }
        port = std::make_unique<SerialPort>(device, config.baud);
        auto link = std::make_shared<DescriptorLink>(asio::posix::stream_descriptor(io, port->release_fd()), device);
        if (sim_pty) {
            SimOptions so = config.sim;
            so.axes.clear();
            for (const auto& j : machine.joints) so.axes += j.output;
            sim = std::make_shared<VirtualPrinter>(io, sim_pty->release_master(), so);
            sim->start();
            spdlog::info("firmware: the virtual printer ({}) on {}", so.reprap ? "RepRapFirmware-like" : "Marlin-like", device);
        } else {
            spdlog::info("firmware: {} at {} baud", device, config.baud);
        }
        service.attach_firmware(link, config.firmware);
    } catch (const IoError& e) {
        spdlog::error("{}", e.what());
        return 4;
    }

    // Sender ends.
    std::unique_ptr<Pty> sender_pty;
    std::optional<asio::ip::tcp::acceptor> acceptor;
    try {
        if (!config.pty.empty()) {
            sender_pty = std::make_unique<Pty>(config.pty);
            auto link = std::make_shared<DescriptorLink>(asio::posix::stream_descriptor(io, sender_pty->release_master()),
                                                         sender_pty->link());
            link->eio_is_transient = true;  // a sender closing the port is not the end of the service
            service.add_sender(link, "pty " + config.pty);
            spdlog::info("senders: open {} (-> {}) as the printer's serial port", config.pty, sender_pty->path());
        }
        if (!config.tcp.empty()) {
            const auto colon = config.tcp.rfind(':');
            if (colon == std::string::npos) throw IoError("sender.tcp: expected host:port, got '" + config.tcp + "'");
            const auto address = asio::ip::make_address(config.tcp.substr(0, colon));
            if (!is_loopback(address) && !config.allow_remote)
                throw IoError("sender.tcp: " + config.tcp + " is not a loopback address; set allow_remote = true to bind it");
            const auto port = static_cast<unsigned short>(std::stoi(config.tcp.substr(colon + 1)));
            acceptor.emplace(io, asio::ip::tcp::endpoint(address, port));
            spdlog::info("senders: tcp {}:{}", address.to_string(), acceptor->local_endpoint().port());
            auto accept = std::make_shared<std::function<void()>>();
            *accept = [&, accept] {
                acceptor->async_accept([&, accept](boost::system::error_code ec, asio::ip::tcp::socket socket) {
                    if (ec) return;
                    socket.set_option(asio::ip::tcp::no_delay(true));
                    const auto peer = socket.remote_endpoint().address().to_string() + ":" + std::to_string(socket.remote_endpoint().port());
                    service.add_sender(std::make_shared<TcpLink>(std::move(socket), "tcp " + peer), "tcp " + peer);
                    (*accept)();
                });
            };
            (*accept)();
        }
    } catch (const std::exception& e) {
        spdlog::error("{}", e.what());
        return 4;
    }

    // SIGTERM/SIGINT: drain, then stop; a second one stops at once (between lines). SIGHUP:
    // reload the machine when idle.
    asio::signal_set signals(io, SIGINT, SIGTERM, SIGHUP);
    bool stopping = false;
    int exit_code = 0;
    std::function<void()> wait_signal = [&] {
        signals.async_wait([&](boost::system::error_code ec, int sig) {
            if (ec) return;
            if (sig == SIGHUP) {
                if (config.source.empty()) {
                    spdlog::warn("SIGHUP: no configuration file to reload");
                } else if (!service.idle()) {
                    spdlog::warn("SIGHUP: a print is running; the configuration is reloaded only when idle");
                } else {
                    try {
                        const auto fresh = load_serve_config(config.source);
                        service.replace_machine(load_configured_machine(fresh));
                        spdlog::info("SIGHUP: reloaded {} (machine {}); port and endpoint changes need a restart", config.source, fresh.machine);
                    } catch (const std::exception& e) {
                        spdlog::error("SIGHUP: {} (keeping the running configuration)", e.what());
                    }
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
                if (outcome.rfind("drained", 0) != 0) exit_code = 0;
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
    if (sim) spdlog::info("virtual printer: executed {}, refused {}, dropped {}", sim->stats().executed, sim->stats().refused, sim->stats().dropped);
    return exit_code;
}

}  // namespace xlate5
