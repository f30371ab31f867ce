// libpcap, loaded at run time: the pcap trace writer is the only user of libpcap, and linking it
// made every program of libnmt's io room load it and the ten libraries it needs (libdbus-1,
// libsystemd, libgcrypt, ...) at start-up, about 1.2 ms of CPU for a `cfgmgr check` that writes
// no trace. Private to libnmt/io; tests of internals include it.
#pragma once

#include <pcap/pcap.h>

#include "cfg/result.hpp"

namespace nmt::detail {

/// The libpcap functions the pcap writer calls. The pointer types come from <pcap/pcap.h>'s
/// prototypes, so a signature change there fails to compile here instead of at run time.
struct PcapLibrary {
  decltype(&::pcap_open_dead) open_dead = nullptr;
  decltype(&::pcap_geterr) geterr = nullptr;
  decltype(&::pcap_close) close = nullptr;
  decltype(&::pcap_dump_open) dump_open = nullptr;
  decltype(&::pcap_dump) dump = nullptr;
  decltype(&::pcap_dump_file) dump_file = nullptr;
  decltype(&::pcap_dump_flush) dump_flush = nullptr;
  decltype(&::pcap_dump_close) dump_close = nullptr;
};

/// libpcap under the SONAME found at build time (libpcap.so.0.8 on Debian), loaded by the first
/// call; later calls (from any thread) return the same functions or the same error. The library
/// stays loaded until the process exits. Fails when the library or one of its functions cannot
/// be loaded, with a message that names the library and the package and ends with dlerror().
cfg::Result<const PcapLibrary*> pcap_library();

/// Loads the library file `soname` (a name the dynamic loader searches for, as dlopen(3) takes
/// it) and looks up the functions, without caching; a library whose functions were all found
/// stays loaded. For tests of the failure path: production code calls pcap_library().
cfg::Result<PcapLibrary> load_pcap_library(const char* soname);

}  // namespace nmt::detail
