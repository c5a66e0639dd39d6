// SPDX-License-Identifier: GPL-3.0-or-later
// Holds the precompiled header the test programs share (tests/CMakeLists.txt).
