// SPDX-License-Identifier: GPL-3.0-or-later
// How the service treats its senders: the `sender.*` settings serve reads (config.hpp) and the
// Service takes as they are (service.hpp), one struct for both so none is copied field by field.
// Data only.
#pragma once
#include <cstddef>

#include "daemon/firmware_protocol.hpp"

namespace xlate5 {

struct SenderLimits {
    std::size_t queue_lines = 64;     // translated lines waiting for the firmware before senders are held
    double busy_interval = marlin::kKeepaliveSeconds;  // seconds between "busy: processing" to a sender held by a full queue
    double hold_seconds = 1.0;        // a pause this long in the senders' stream ends the look-back window
    std::size_t max_pending = 256;    // lines of one sender read ahead of the queue before it is read no further
    std::size_t max_tcp = 16;         // TCP senders at once (each holds a descriptor and buffers); more are turned away (docs/limits.md)
    double idle_seconds = 600;        // a TCP sender silent this long, and not printing, is disconnected
};

}  // namespace xlate5
