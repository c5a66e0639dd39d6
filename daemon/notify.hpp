// SPDX-License-Identifier: GPL-3.0-or-later
// systemd's notification protocol (sd_notify(3)), spoken directly: one datagram of
// "KEY=VALUE\n..." lines to the socket named by $NOTIFY_SOCKET (a path, or '@' for the abstract
// namespace). Stage: the service's lifecycle; calls the socket API only, no libsystemd.
#pragma once
#include <string_view>

namespace xlate5 {

// Sends `state` ("READY=1", "STATUS=printing…", "STOPPING=1"). Returns false when not run under
// systemd (no $NOTIFY_SOCKET) or the datagram could not be sent; the service carries on either way.
bool notify_systemd(std::string_view state);

}  // namespace xlate5
