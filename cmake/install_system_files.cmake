# Run by `cmake --install` (and by CPack), not when configuring: the system files whose place or
# content depends on the prefix given at install time (`cmake --install build --prefix /usr`,
# CPack's /usr), which a configure-time path would get wrong.
#   - the configuration directory: /etc for the prefix /usr, /etc/opt/... for /opt/...,
#     PREFIX/etc otherwise (GNUInstallDirs' rule, applied to the install-time prefix);
#   - the example configurations: one the admin edited is kept, the shipped one put beside it
#     as NAME.dist (the .deb marks them conffiles and dpkg does the same);
#   - the systemd units, their paths (/usr/bin, /etc/pneu, /usr/share/doc/pneu in the source)
#     rewritten to this prefix's.
# Set by the caller (systemd/CMakeLists.txt): PNEU_UNIT_SOURCES, PNEU_CONFIG_SOURCES,
# PNEU_BINDIR, PNEU_DOCDIR (relative to the prefix, or absolute), PNEU_STAGING_DIR.
function(pneu_under_prefix out dir)
  if(IS_ABSOLUTE "${dir}")
    set(${out} "${dir}" PARENT_SCOPE)
  else()
    set(${out} "${CMAKE_INSTALL_PREFIX}/${dir}" PARENT_SCOPE)
  endif()
endfunction()

if(CMAKE_INSTALL_PREFIX STREQUAL "/usr")
  set(sysconfdir "/etc")
elseif(CMAKE_INSTALL_PREFIX MATCHES "^/opt/")
  set(sysconfdir "/etc${CMAKE_INSTALL_PREFIX}")
else()
  set(sysconfdir "${CMAKE_INSTALL_PREFIX}/etc")
endif()
pneu_under_prefix(bindir "${PNEU_BINDIR}")
pneu_under_prefix(docdir "${PNEU_DOCDIR}")

foreach(config IN LISTS PNEU_CONFIG_SOURCES)
  get_filename_component(name "${config}" NAME)
  set(target "$ENV{DESTDIR}${sysconfdir}/pneu/${name}")
  if(EXISTS "${target}")
    file(SHA256 "${target}" installed)
    file(SHA256 "${config}" shipped)
    if(NOT installed STREQUAL shipped)
      message(STATUS "Kept: ${target} (edited); the shipped one is ${name}.dist beside it")
      file(MAKE_DIRECTORY "${PNEU_STAGING_DIR}")
      file(COPY_FILE "${config}" "${PNEU_STAGING_DIR}/${name}.dist")
      file(INSTALL DESTINATION "${sysconfdir}/pneu" TYPE FILE FILES "${PNEU_STAGING_DIR}/${name}.dist")
      continue()
    endif()
  endif()
  file(INSTALL DESTINATION "${sysconfdir}/pneu" TYPE FILE FILES "${config}")
endforeach()

foreach(unit IN LISTS PNEU_UNIT_SOURCES)
  get_filename_component(name "${unit}" NAME)
  file(READ "${unit}" text)
  string(REPLACE "/usr/bin/" "${bindir}/" text "${text}")
  string(REPLACE "/etc/pneu/" "${sysconfdir}/pneu/" text "${text}")
  string(REPLACE "/usr/share/doc/pneu/" "${docdir}/" text "${text}")
  file(WRITE "${PNEU_STAGING_DIR}/${name}" "${text}")
  file(INSTALL DESTINATION "${CMAKE_INSTALL_PREFIX}/lib/systemd/system" TYPE FILE FILES "${PNEU_STAGING_DIR}/${name}")
endforeach()
