# SPDX-License-Identifier: GPL-3.0-or-later
# Installing and packaging: `cmake --install build` (prefix /usr/local by default) and a Debian
# package from `cpack` in the build directory (prefix /usr). Both lay out the same tree.

# The unit names the executable and the documentation by their installed paths, which are known
# only at install time (cpack installs under /usr whatever the build's prefix), so it is written
# then.
set(XLATE5_UNIT_TEMPLATE ${PROJECT_SOURCE_DIR}/systemd/xlate5@.service.in)
install(CODE "
  set(XLATE5_BIN \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_BINDIR}/xlate5\")
  set(XLATE5_DOC_DIR \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_DOCDIR}\")
  configure_file(\"${XLATE5_UNIT_TEMPLATE}\" \"${PROJECT_BINARY_DIR}/install/xlate5@.service\" @ONLY)
  file(INSTALL \"${PROJECT_BINARY_DIR}/install/xlate5@.service\" DESTINATION \"\${CMAKE_INSTALL_PREFIX}/lib/systemd/system\")
")

# Debian's copyright file (machine-readable format 1.0) and the changelog, compressed as Debian
# does (gzip -9n: no name or time stamp, so the package is reproducible). A native package's
# changelog is changelog.gz.
install(FILES ${PROJECT_SOURCE_DIR}/packaging/deb/copyright DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(CODE "
  file(MAKE_DIRECTORY \"${PROJECT_BINARY_DIR}/install\")
  execute_process(COMMAND gzip -9n -c \"${PROJECT_SOURCE_DIR}/packaging/deb/changelog\"
                  OUTPUT_FILE \"${PROJECT_BINARY_DIR}/install/changelog.gz\" COMMAND_ERROR_IS_FATAL ANY)
  file(INSTALL \"${PROJECT_BINARY_DIR}/install/changelog.gz\" DESTINATION \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_DOCDIR}\")
")

# The examples the README's first steps translate and print.
install(FILES ${PROJECT_SOURCE_DIR}/examples/rw2_flared_wall.gcode ${PROJECT_SOURCE_DIR}/examples/pentarod_dome.gcode
        DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples)

# cpack packages what is built; it does not build everything else first (the package test runs
# cpack under ctest, in a tree where only some targets may be built).
set(CMAKE_SKIP_INSTALL_ALL_DEPENDENCY ON)

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME xlate5)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "5-axis G-code translator for stock Marlin and RepRapFirmware")
set(CPACK_PACKAGE_DESCRIPTION "xlate5 translates vendor-neutral 5-axis G-code (tip and tool orientation)
into joint-space G-code for stock Marlin or RepRapFirmware with closed-form
inverse kinematics: offline, as a filter, or as a service between a sender
(OctoPrint, Printrun) and the printer.")
# The Maintainer field (and the changelog's signature): override for a real package build.
set(XLATE5_MAINTAINER "xlate5 developers <xlate5-dev@example.org>" CACHE STRING "the package's Maintainer field")
set(CPACK_PACKAGE_CONTACT "${XLATE5_MAINTAINER}")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)  # Depends: from the libraries the binary links, and
set(CPACK_DEBIAN_PACKAGE_DEPENDS "adduser")  # postinst's adduser
# The maintainer scripts (packaging/deb/): postinst makes the xlate5 user, prerm and postrm stop
# running xlate5@ instances on removal. Mode 0755, as dpkg and lintian want.
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${PROJECT_SOURCE_DIR}/packaging/deb/postinst ${PROJECT_SOURCE_DIR}/packaging/deb/prerm ${PROJECT_SOURCE_DIR}/packaging/deb/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "systemd")
set(CPACK_STRIP_FILES ON)
# Only this project's files: no install rules of the test or benchmark programs.
set(CPACK_INSTALL_CMAKE_PROJECTS "${PROJECT_BINARY_DIR};${PROJECT_NAME};ALL;/")
include(CPack)
