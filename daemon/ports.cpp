// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/ports.hpp"

#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <grp.h>
#include <sys/stat.h>
#include <filesystem>
#include <libserialport.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include "translators/error.hpp"

namespace xlate5 {
namespace {

std::string sp_error(const std::string& device, const char* what) {
    char* msg = sp_last_error_message();
    std::string s = device + ": " + what + ": " + (msg ? msg : "unknown error");
    if (msg) sp_free_error_message(msg);
    return s;
}

}  // namespace

void make_raw(int fd) {
    termios t{};
    if (::tcgetattr(fd, &t) != 0) return;
    ::cfmakeraw(&t);
    t.c_cc[VMIN] = 1;
    t.c_cc[VTIME] = 0;
    ::tcsetattr(fd, TCSANOW, &t);
}

SerialPort::SerialPort(const std::string& device, int baud) : device_(device) {
    if (sp_get_port_by_name(device.c_str(), &port_) != SP_OK) {
        // libserialport knows only the ports the kernel lists (not pseudo-terminals): any other
        // terminal device is opened with termios.
        port_ = nullptr;
        open_tty(baud);
        return;
    }
    if (sp_open(port_, SP_MODE_READ_WRITE) != SP_OK) {
        const auto msg = sp_error(device, "cannot open");
        sp_free_port(port_);
        port_ = nullptr;
        throw IoError(msg);
    }
    const bool ok = sp_set_baudrate(port_, baud) == SP_OK && sp_set_bits(port_, 8) == SP_OK &&
                    sp_set_parity(port_, SP_PARITY_NONE) == SP_OK && sp_set_stopbits(port_, 1) == SP_OK &&
                    sp_set_flowcontrol(port_, SP_FLOWCONTROL_NONE) == SP_OK;
    if (!ok) {
        const auto msg = sp_error(device, ("cannot set " + std::to_string(baud) + " baud 8N1").c_str());
        sp_close(port_);
        sp_free_port(port_);
        port_ = nullptr;
        throw IoError(msg);
    }
}

void SerialPort::open_tty(int baud) {
    fd_ = ::open(device_.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (fd_ < 0) throw IoError(device_ + ": cannot open: " + std::strerror(errno));
    if (!::isatty(fd_)) {
        ::close(fd_);
        fd_ = -1;
        throw IoError(device_ + ": not a serial port or terminal");
    }
    termios t{};
    ::tcgetattr(fd_, &t);
    ::cfmakeraw(&t);
    t.c_cflag |= CLOCAL | CREAD;
    t.c_cc[VMIN] = 1;
    t.c_cc[VTIME] = 0;
    speed_t speed = B115200;
    switch (baud) {
        case 9600: speed = B9600; break;
        case 19200: speed = B19200; break;
        case 38400: speed = B38400; break;
        case 57600: speed = B57600; break;
        case 115200: speed = B115200; break;
        case 230400: speed = B230400; break;
        case 460800: speed = B460800; break;
        case 500000: speed = B500000; break;
        case 921600: speed = B921600; break;
        case 1000000: speed = B1000000; break;
        default: break;  // a pseudo-terminal has no speed; real ports go through libserialport
    }
    ::cfsetspeed(&t, speed);
    ::tcsetattr(fd_, TCSANOW, &t);
}

SerialPort::~SerialPort() {
    if (fd_ >= 0) ::close(fd_);
    if (port_) {
        sp_close(port_);
        sp_free_port(port_);
    }
}

int SerialPort::release_fd() {
    int fd = fd_;
    if (port_ && sp_get_port_handle(port_, &fd) != SP_OK) throw IoError(sp_error(device_, "no descriptor"));
    const int copy = ::fcntl(fd, F_DUPFD_CLOEXEC, 0);
    if (copy < 0) throw IoError(device_ + ": dup: " + std::strerror(errno));
    return copy;
}

Pty::Pty(const std::string& link_path, const std::string& group) {
    int slave = -1;
    char name[256] = {};
    if (::openpty(&master_, &slave, name, nullptr, nullptr) != 0) throw IoError(std::string("openpty: ") + std::strerror(errno));
    ::fcntl(master_, F_SETFD, FD_CLOEXEC);
    if (!group.empty()) {
        const struct group* g = ::getgrnam(group.c_str());
        if (!g || ::fchown(slave, uid_t(-1), g->gr_gid) != 0 || ::fchmod(slave, 0660) != 0) {
            const std::string why = g ? std::strerror(errno) : "no such group";
            ::close(slave);
            ::close(master_);
            throw IoError(std::string(name) + ": cannot give it to group " + group + ": " + why);
        }
    }
    make_raw(slave);  // a sender that does not configure the port must not get its lines echoed back
    ::close(slave);   // reading the master then fails with EIO until a sender opens the slave
    path_ = name;
    if (!link_path.empty()) {
        std::error_code ec;
        const auto parent = std::filesystem::path(link_path).parent_path();
        if (!parent.empty()) std::filesystem::create_directories(parent, ec);
        if (std::filesystem::is_symlink(link_path, ec)) std::filesystem::remove(link_path, ec);
        std::filesystem::create_symlink(path_, link_path, ec);
        if (ec) {
            ::close(master_);
            throw IoError(link_path + ": cannot link to " + path_ + ": " + ec.message());
        }
        link_ = link_path;
    }
}

Pty::~Pty() {
    if (!link_.empty()) {
        std::error_code ec;
        if (std::filesystem::is_symlink(link_, ec) && std::filesystem::read_symlink(link_, ec) == path_)
            std::filesystem::remove(link_, ec);
    }
    if (master_ >= 0) ::close(master_);
}

int Pty::release_master() {
    const int fd = master_;
    master_ = -1;
    return fd;
}

std::vector<PortInfo> list_ports() {
    std::vector<PortInfo> out;
    sp_port** ports = nullptr;
    if (sp_list_ports(&ports) != SP_OK) return out;
    for (int i = 0; ports[i]; ++i) {
        sp_port* p = ports[i];
        PortInfo info;
        info.path = sp_get_port_name(p);
        if (const char* d = sp_get_port_description(p)) info.description = d;
        switch (sp_get_port_transport(p)) {
            case SP_TRANSPORT_USB: {
                info.transport = "usb";
                int vid = -1, pid = -1;
                if (sp_get_port_usb_vid_pid(p, &vid, &pid) == SP_OK) info.usb_vid = vid, info.usb_pid = pid;
                if (const char* s = sp_get_port_usb_manufacturer(p)) info.manufacturer = s;
                if (const char* s = sp_get_port_usb_product(p)) info.product = s;
                if (const char* s = sp_get_port_usb_serial(p)) info.serial = s;
                break;
            }
            case SP_TRANSPORT_BLUETOOTH: info.transport = "bluetooth"; break;
            default: info.transport = "native"; break;
        }
        out.push_back(std::move(info));
    }
    sp_free_port_list(ports);
    return out;
}

}  // namespace xlate5
