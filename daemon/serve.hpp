// `xlate5 serve` and `xlate5 ports`: the service's lifecycle (ports, endpoints, signals,
// logging) around the Service.
#pragma once
#include "daemon/config.hpp"

namespace xlate5 {

// Runs until SIGTERM/SIGINT (queue drained, or stopped between lines after drain_timeout).
// Returns the process exit code.
int run_serve(const ServeConfig& config);

// Lists serial ports with their USB vendor/product and description.
int run_ports();

}  // namespace xlate5
