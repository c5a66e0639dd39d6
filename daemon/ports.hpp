// SPDX-License-Identifier: GPL-3.0-or-later
// The ends the service opens: the firmware's serial port (libserialport, so any baud rate the
// driver takes, 250000 included), the pseudo-terminal a sender opens as if it were the printer,
// and the list of serial ports for `xlate5 ports`.
#pragma once
#include <memory>
#include <string>
#include <vector>

struct sp_port;

namespace xlate5 {

// An open serial port. `fd()` is a duplicate of the port's descriptor for Asio to own.
class SerialPort {
public:
    // Opens `device` at `baud`, 8N1, no flow control. Throws IoError naming the device and cause.
    SerialPort(const std::string& device, int baud);
    ~SerialPort();
    SerialPort(const SerialPort&) = delete;
    SerialPort& operator=(const SerialPort&) = delete;
    int release_fd();  // a descriptor Asio takes ownership of
    const std::string& device() const { return device_; }

private:
    void open_tty(int baud);
    sp_port* port_ = nullptr;  // a port libserialport knows (USB, native UART)
    int fd_ = -1;              // any other terminal (a pseudo-terminal)
    std::string device_;
};

// A pseudo-terminal for a sender: raw, no echo. `path` is the slave device; with a link path,
// a symlink to it is made (replacing a stale one) and removed on destruction. With a group, the
// device is given to that group, read-write (a sender running as another user, e.g. OctoPrint
// in dialout, can open it).
class Pty {
public:
    explicit Pty(const std::string& link_path = "", const std::string& group = "");
    ~Pty();
    Pty(const Pty&) = delete;
    Pty& operator=(const Pty&) = delete;
    int release_master();  // the master descriptor, for Asio to own
    const std::string& path() const { return path_; }
    const std::string& link() const { return link_; }

private:
    int master_ = -1;
    std::string path_, link_;
};

// Puts a terminal descriptor in raw mode (no echo, no line editing, no CR/LF mapping).
void make_raw(int fd);

struct PortInfo {
    std::string path, description, transport, manufacturer, product, serial;
    int usb_vid = -1, usb_pid = -1;
};
std::vector<PortInfo> list_ports();

}  // namespace xlate5
