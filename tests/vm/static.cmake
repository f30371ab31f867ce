# Included right after project() in the VM tier's static build (run-vm-tests.sh passes it as
# CMAKE_PROJECT_INCLUDE): libraries found by find_library and pkg-config IMPORTED_TARGETs are the
# static archives, since a -static link cannot use a shared object.
set(CMAKE_FIND_LIBRARY_SUFFIXES .a)
