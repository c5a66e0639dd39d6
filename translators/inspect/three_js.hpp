// SPDX-License-Identifier: GPL-3.0-or-later
// three.js and its OrbitControls as Debian's libjs-three ships them, inlined at build time
// (translators/CMakeLists.txt reads the installed files into three_js.cpp) so the preview page
// is one file that needs no network. May call: nothing.
#pragma once

namespace xlate5::three_js {
extern const char* const kSource;         // three.min.js
extern const char* const kOrbitControls;  // examples/js/controls/OrbitControls.js
extern const char* const kRevision;       // "111" for Debian 12's libjs-three
}  // namespace xlate5::three_js
