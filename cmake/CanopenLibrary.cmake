# canopen_add_library(): one library of this project, built once and linked two ways.
#
#   canopen_add_library(NAME SOURCES src... INCLUDE dir [PRIVATE_INCLUDE dir]
#                       [PUBLIC deps...] [PRIVATE deps...])
#
# makes, from one set of objects (position-independent, compiled once):
#   NAME          static archive libcanopen-NAME.a, alias canopen::NAME: what the tools, tests
#                 and benchmarks of this tree link, and `canopen::NAME` of the installed
#                 package when the consumer asks for static libraries;
#   NAME_shared   shared object libcanopen-NAME.so.<major>.<minor> (unless CANOPEN_SHARED_LIBS is
#                 OFF), alias canopen::NAME_shared; `canopen::NAME` of the installed package by
#                 default.
# PUBLIC deps are other libraries of this project (canopen::X; the shared library links X_shared)
# whose headers the public headers include; PRIVATE deps are third-party targets. Underscores in
# NAME become dashes in the file name (nmt_core -> libcanopen-nmt-core.so).
include_guard(GLOBAL)

set(CANOPEN_LIBRARIES_STATIC "" CACHE INTERNAL "")
set(CANOPEN_LIBRARIES_SHARED "" CACHE INTERNAL "")

function(canopen_add_library name)
  cmake_parse_arguments(PARSE_ARGV 1 arg "" "INCLUDE;PRIVATE_INCLUDE" "SOURCES;PUBLIC;PRIVATE")
  string(REPLACE "_" "-" file_name "canopen-${name}")

  add_library(${name}_objects OBJECT ${arg_SOURCES})
  # -fno-semantic-interposition: position-independent code that GCC may still inline within
  # the library, so the archive is as fast as before it was built from PIC objects.
  set_target_properties(${name}_objects PROPERTIES POSITION_INDEPENDENT_CODE ON)
  target_compile_options(${name}_objects PRIVATE -fno-semantic-interposition)
  target_include_directories(${name}_objects PUBLIC $<BUILD_INTERFACE:${arg_INCLUDE}>)
  if(arg_PRIVATE_INCLUDE)
    target_include_directories(${name}_objects PRIVATE ${arg_PRIVATE_INCLUDE})
  endif()
  target_link_libraries(${name}_objects PUBLIC ${arg_PUBLIC} PRIVATE ${arg_PRIVATE})

  set(kinds static)
  if(CANOPEN_SHARED_LIBS)
    list(APPEND kinds shared)
  endif()
  foreach(kind IN LISTS kinds)
    if(kind STREQUAL "static")
      set(target ${name})
      add_library(${target} STATIC $<TARGET_OBJECTS:${name}_objects>)
      set(deps ${arg_PUBLIC})
    else()
      set(target ${name}_shared)
      add_library(${target} SHARED $<TARGET_OBJECTS:${name}_objects>)
      # 0.x: every minor version may change the ABI. $ORIGIN: the libraries find each other
      # wherever the package was installed.
      set_target_properties(${target} PROPERTIES
        VERSION ${PROJECT_VERSION}
        SOVERSION ${PROJECT_VERSION_MAJOR}.${PROJECT_VERSION_MINOR}
        INSTALL_RPATH "$ORIGIN")
      set(deps "")
      foreach(dep IN LISTS arg_PUBLIC)
        list(APPEND deps ${dep}_shared)
      endforeach()
    endif()
    add_library(canopen::${target} ALIAS ${target})
    set_target_properties(${target} PROPERTIES OUTPUT_NAME ${file_name} EXPORT_NAME ${name})
    target_include_directories(${target} PUBLIC
      $<BUILD_INTERFACE:${arg_INCLUDE}>
      $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}/canopen>)
    target_link_libraries(${target} PUBLIC ${deps} PRIVATE ${arg_PRIVATE})
    set(list_name CANOPEN_LIBRARIES_${kind})
    string(TOUPPER ${list_name} list_name)
    set(${list_name} ${${list_name}} ${target} CACHE INTERNAL "")
  endforeach()
endfunction()

# canopen_add_umbrella(NAME deps...): an INTERFACE target linking several libraries (static NAME
# and, with shared libraries, NAME_shared), installed beside them.
function(canopen_add_umbrella name)
  add_library(${name} INTERFACE)
  add_library(canopen::${name} ALIAS ${name})
  target_link_libraries(${name} INTERFACE ${ARGN})
  set_target_properties(${name} PROPERTIES EXPORT_NAME ${name})
  set(CANOPEN_LIBRARIES_STATIC ${CANOPEN_LIBRARIES_STATIC} ${name} CACHE INTERNAL "")
  if(CANOPEN_SHARED_LIBS)
    set(deps "")
    foreach(dep IN LISTS ARGN)
      list(APPEND deps ${dep}_shared)
    endforeach()
    add_library(${name}_shared INTERFACE)
    add_library(canopen::${name}_shared ALIAS ${name}_shared)
    target_link_libraries(${name}_shared INTERFACE ${deps})
    set_target_properties(${name}_shared PROPERTIES EXPORT_NAME ${name})
    set(CANOPEN_LIBRARIES_SHARED ${CANOPEN_LIBRARIES_SHARED} ${name}_shared CACHE INTERNAL "")
  endif()
endfunction()
