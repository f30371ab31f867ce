# Debian packages with CPack: `cpack -G DEB` in a build tree (see README, "Install"). One package
# per install component (cmake/CanopenInstall.cmake):
#   libcanopen<major>.<minor>  shared libraries and schemas; Depends from dpkg-shlibdeps
#   libcanopen-dev             headers, static libraries, CMake package, pkg-config files;
#                              Depends on the runtime package and the -dev packages of the static
#                              libraries' dependencies (a static link needs them)
#   canopen-tools              dcf2concise, cfgmgr, man pages; Depends from dpkg-shlibdeps and
#                              the runtime package (cfgmgr check reads its schemas)
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

set(canopen_runtime_package libcanopen${PROJECT_VERSION_MAJOR}.${PROJECT_VERSION_MINOR})
set(CPACK_DEBIAN_RUNTIME_PACKAGE_NAME ${canopen_runtime_package})
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SECTION libs)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_GENERATE_SHLIBS ON)
set(CPACK_COMPONENT_RUNTIME_DESCRIPTION
    "CANopen commissioning libraries (libcfg, libnmt) and the CiA 301/302 schemas")

set(CPACK_DEBIAN_DEV_PACKAGE_NAME libcanopen-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS "zlib1g-dev, libmsgpack-dev, libpcap-dev")
set(CPACK_COMPONENT_DEV_DESCRIPTION
    "CANopen commissioning libraries: headers, static libraries, CMake package, pkg-config files")

set(CPACK_DEBIAN_TOOLS_PACKAGE_NAME canopen-tools)
set(CPACK_DEBIAN_TOOLS_PACKAGE_SECTION electronics)
set(CPACK_COMPONENT_TOOLS_DESCRIPTION
    "CANopen commissioning tools: dcf2concise (DCF to concise DCF), cfgmgr (check, fmt, simulate)")

if(CANOPEN_SHARED_LIBS)
  set(CPACK_COMPONENT_DEV_DEPENDS runtime)
  set(CPACK_COMPONENT_TOOLS_DEPENDS runtime)
endif()

include(CPack)
