# What `cmake --install` puts where, in three components (the Debian packages of
# cmake/CanopenPackaging.cmake):
#   runtime  shared libraries, the schemas                    -> libcanopen<major>.<minor>
#   dev      headers, static libraries, the CMake package,
#            pkg-config files, the .so links                  -> libcanopen-dev
#   tools    dcf2concise, cfgmgr and their man pages          -> canopen-tools
#
# The CMake package `canopen` (find_package(canopen)) defines canopen::cfg, canopen::nmt_core,
# canopen::nmt_sim, canopen::nmt_io and canopen::nmt (all three rooms): the shared libraries,
# or the static ones when the consumer sets CANOPEN_USE_STATIC_LIBS ON (or none are installed).
# pkg-config: canopen-cfg, canopen-nmt-core, canopen-nmt-sim, canopen-nmt-io, canopen-nmt.
include_guard(GLOBAL)
include(CMakePackageConfigHelpers)

set(CANOPEN_CMAKE_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/canopen)

# Headers keep their "cfg/x.hpp" / "nmt/x.hpp" names under <includedir>/canopen. CANOPEN_CORE_ONLY
# installs canopen::cfg and canopen::nmt_core with their headers and pkg-config files only.
set(header_dirs libcfg/include libnmt/core/include)
if(NOT CANOPEN_CORE_ONLY)
  list(APPEND header_dirs libnmt/sim/include libnmt/io/include)
endif()
foreach(dir ${header_dirs})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/canopen
          COMPONENT dev FILES_MATCHING PATTERN "*.hpp")
endforeach()

install(TARGETS ${CANOPEN_LIBRARIES_STATIC} EXPORT canopen-static-targets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev)
install(EXPORT canopen-static-targets NAMESPACE canopen::
        DESTINATION ${CANOPEN_CMAKE_INSTALL_DIR} COMPONENT dev)
if(CANOPEN_SHARED_LIBS)
  install(TARGETS ${CANOPEN_LIBRARIES_SHARED} EXPORT canopen-shared-targets
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT runtime NAMELINK_COMPONENT dev)
  install(EXPORT canopen-shared-targets NAMESPACE canopen::
          DESTINATION ${CANOPEN_CMAKE_INSTALL_DIR} COMPONENT dev)
endif()

configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/canopenConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/canopenConfig.cmake
                              INSTALL_DESTINATION ${CANOPEN_CMAKE_INSTALL_DIR}
                              PATH_VARS CANOPEN_SCHEMA_INSTALL_DIR)
# 0.x: a minor version may change the API.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/canopenConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/canopenConfig.cmake
              ${PROJECT_BINARY_DIR}/canopenConfigVersion.cmake
        DESTINATION ${CANOPEN_CMAKE_INSTALL_DIR} COMPONENT dev)

# pkg-config files, relocatable: the prefix is found from the .pc file's own directory.
file(RELATIVE_PATH CANOPEN_PC_PREFIX_FROM_PCFILEDIR ${CMAKE_INSTALL_FULL_LIBDIR}/pkgconfig
     ${CMAKE_INSTALL_PREFIX})
string(REGEX REPLACE "/$" "" CANOPEN_PC_PREFIX_FROM_PCFILEDIR "${CANOPEN_PC_PREFIX_FROM_PCFILEDIR}")
# canopen_pkg_config(MODULE DESCRIPTION REQUIRES REQUIRES_PRIVATE LIBRARY [SYSTEM_LIBS...]):
# SYSTEM_LIBS (names without -l) go to Libs.private: what a static link needs beyond the
# Requires.private modules.
function(canopen_pkg_config module description requires requires_private library)
  set(PC_MODULE ${module})
  set(PC_DESCRIPTION ${description})
  set(PC_REQUIRES ${requires})
  set(PC_REQUIRES_PRIVATE ${requires_private})
  list(TRANSFORM ARGN PREPEND "-l" OUTPUT_VARIABLE system_libs)
  list(JOIN system_libs " " PC_LIBS_PRIVATE)
  if(library)
    set(PC_LIBS "-L\${libdir} -l${library}")
  else()
    set(PC_LIBS "")
  endif()
  configure_file(${PROJECT_SOURCE_DIR}/cmake/canopen.pc.in ${PROJECT_BINARY_DIR}/pkgconfig/${module}.pc
                 @ONLY)
  install(FILES ${PROJECT_BINARY_DIR}/pkgconfig/${module}.pc
          DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT dev)
endfunction()
canopen_pkg_config(canopen-cfg
                   "CANopen object dictionary, CiA 306 EDS/DCF, CiA 302 concise DCF" ""
                   "zlib yaml-cpp" canopen-cfg)
canopen_pkg_config(canopen-nmt-core
                   "CANopen protocol engines (frames, SDO, NMT slave, error control, EMCY)"
                   canopen-cfg "" canopen-nmt-core)
if(NOT CANOPEN_CORE_ONLY)
  canopen_pkg_config(canopen-nmt-sim "CANopen simulated bus and simulated devices"
                     canopen-nmt-core "" canopen-nmt-sim)
  # libpcap is loaded with dlopen() when a pcap trace is opened (libnmt/CMakeLists.txt): a static
  # link needs the dynamic loader's library (libdl before glibc 2.34), not libpcap.
  canopen_pkg_config(canopen-nmt-io "CANopen bus drivers: SocketCAN, UDP multicast, traces"
                     canopen-nmt-core msgpack canopen-nmt-io ${CMAKE_DL_LIBS})
  canopen_pkg_config(canopen-nmt "CANopen libnmt: protocol engines, simulation and bus drivers"
                     "canopen-nmt-core canopen-nmt-sim canopen-nmt-io" "" "")
endif()

install(DIRECTORY ${PROJECT_SOURCE_DIR}/schemas/ DESTINATION ${CANOPEN_SCHEMA_INSTALL_DIR}
        COMPONENT runtime FILES_MATCHING PATTERN "*.eds")
