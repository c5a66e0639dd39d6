// SPDX-License-Identifier: GPL-3.0-or-later
// Whole small files (machine files, compensation tables, keep-out lists, measurement tables, the
// service's configuration) read into memory with a bound, so an endless file (/dev/zero, a FIFO
// that never ends) is refused instead of growing memory. No stage; calls nothing of the pipeline.
#pragma once
#include <cstddef>
#include <string>

namespace xlate5 {

// The file at `path` if it holds at most `max_bytes`. Throws IoError when it cannot be opened or
// read, and InputError naming the line and column of its first byte past the bound when it is
// longer ("path:line:column: longer than N bytes, the bound for <what> (docs/limits.md)").
std::string read_small_file(const std::string& path, std::size_t max_bytes, const std::string& what);

}  // namespace xlate5
