# Debian packages with CPack: `cpack -G DEB` in a build tree (see README, "Install"). One package
# per install component (cmake/CanopenInstall.cmake):
#   libcanopen<major>.<minor>  shared libraries and schemas; Depends from dpkg-shlibdeps and
#                              libpcap (see below)
#   libcanopen-dev             headers, static libraries, CMake package, pkg-config files;
#                              Depends on the runtime package and the -dev packages of the static
#                              libraries' dependencies (a static link needs them)
#   canopen-tools              dcf2concise, cfgmgr, man pages; Depends from dpkg-shlibdeps,
#                              libpcap and the runtime package (cfgmgr check reads its schemas)
include_guard(GLOBAL)

set(CPACK_PACKAGE_NAME canopen)
set(CPACK_PACKAGE_VENDOR "CANopen commissioning toolchain")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "CANopen network commissioning: libraries and tools")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "CANopen commissioning toolchain maintainers <maintainers@localhost>")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)

set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL tools dev)
if(CANOPEN_SHARED_LIBS)
  list(APPEND CPACK_COMPONENTS_ALL runtime)
endif()
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_ENABLE_COMPONENT_DEPENDS ON)

# libnmt_io loads libpcap with dlopen() (libnmt/CMakeLists.txt), out of dpkg-shlibdeps' sight: the
# packages holding libnmt_io (the runtime package) and cfgmgr (the tools, linked with the static
# libraries) name it themselves, as dpkg-shlibdeps would: the shlibs entry of the package that
# holds the library found at build time (on Debian 12 "libpcap0.8 (>= 1.10.3)").
set(canopen_pcap_depends libpcap0.8)
find_program(CANOPEN_DPKG_QUERY dpkg-query)
get_filename_component(pcap_dir ${CANOPEN_PCAP_LIBRARY} DIRECTORY)
if(CANOPEN_DPKG_QUERY AND CANOPEN_PCAP_SONAME MATCHES "^(.+)\\.so\\.(.+)$")
  # shlibs lines read "<library> <soversion> <dependency>" (deb-shlibs(5)).
  set(shlibs_key "${CMAKE_MATCH_1} ${CMAKE_MATCH_2} ")
  execute_process(COMMAND ${CANOPEN_DPKG_QUERY} -S ${pcap_dir}/${CANOPEN_PCAP_SONAME}
                  OUTPUT_VARIABLE pcap_owner RESULT_VARIABLE status ERROR_QUIET)
  if(status EQUAL 0 AND pcap_owner MATCHES "^([^ ,]+): ")
    execute_process(COMMAND ${CANOPEN_DPKG_QUERY} --control-show ${CMAKE_MATCH_1} shlibs
                    OUTPUT_VARIABLE pcap_shlibs RESULT_VARIABLE status ERROR_QUIET)
    if(status EQUAL 0)
      string(REPLACE "\n" ";" pcap_shlibs "${pcap_shlibs}")
      foreach(line IN LISTS pcap_shlibs)
        string(FIND "${line}" "${shlibs_key}" at)
        if(at EQUAL 0)
          string(LENGTH "${shlibs_key}" length)
          string(SUBSTRING "${line}" ${length} -1 canopen_pcap_depends)
        endif()
      endforeach()
    endif()
  endif()
endif()
message(STATUS "Debian packages with cfgmgr or libnmt_io depend on: ${canopen_pcap_depends}")

set(canopen_runtime_package libcanopen${PROJECT_VERSION_MAJOR}.${PROJECT_VERSION_MINOR})
set(CPACK_DEBIAN_RUNTIME_PACKAGE_NAME ${canopen_runtime_package})
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SECTION libs)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_GENERATE_SHLIBS ON)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_DEPENDS "${canopen_pcap_depends}")
set(CPACK_COMPONENT_RUNTIME_DESCRIPTION
    "CANopen commissioning libraries (libcfg, libnmt) and the CiA 301/302 schemas")

set(CPACK_DEBIAN_DEV_PACKAGE_NAME libcanopen-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
# No libpcap-dev: the headers do not include pcap.h and the archives do not link libpcap.
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS "zlib1g-dev, libyaml-cpp-dev, libmsgpack-dev")
set(CPACK_COMPONENT_DEV_DESCRIPTION
    "CANopen commissioning libraries: headers, static libraries, CMake package, pkg-config files")

set(CPACK_DEBIAN_TOOLS_PACKAGE_NAME canopen-tools)
set(CPACK_DEBIAN_TOOLS_PACKAGE_SECTION electronics)
set(CPACK_DEBIAN_TOOLS_PACKAGE_DEPENDS "${canopen_pcap_depends}")
set(CPACK_COMPONENT_TOOLS_DESCRIPTION
    "CANopen commissioning tools: dcf2concise (DCF to concise DCF), cfgmgr (check, fmt, simulate)")

if(CANOPEN_SHARED_LIBS)
  set(CPACK_COMPONENT_DEV_DEPENDS runtime)
  set(CPACK_COMPONENT_TOOLS_DEPENDS runtime)
endif()

include(CPack)
