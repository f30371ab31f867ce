#include "pcap_library.hpp"

#include <dlfcn.h>

#include <string>

#ifndef CANOPEN_PCAP_SONAME
#error "libnmt/CMakeLists.txt defines CANOPEN_PCAP_SONAME"
#endif

namespace nmt::detail {

namespace {

cfg::Error missing(const std::string& reason) {
  return cfg::Error{"writing a pcap trace needs libpcap (Debian package libpcap0.8): " + reason +
                        "; install it (apt-get install libpcap0.8), or give a .log trace "
                        "(candump format), which needs no library",
                    cfg::ErrorCategory::Io};
}

// dlerror() after a failed dlopen/dlsym; never null then, but a message must not depend on it.
std::string last_dl_error() {
  const char* text = ::dlerror();
  return text != nullptr ? text : "unknown dynamic loader error";
}

template <class Function>
bool resolve(void* handle, const char* name, Function& function) {
  // POSIX dlsym: a data pointer converted to a function pointer (conditionally supported in
  // C++, always so on POSIX systems).
  function = reinterpret_cast<Function>(::dlsym(handle, name));
  return function != nullptr;
}

}  // namespace

cfg::Result<PcapLibrary> load_pcap_library(const char* soname) {
  // RTLD_LOCAL: libpcap's symbols serve only the lookups below, never another library's.
  void* handle = ::dlopen(soname, RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) return missing(last_dl_error());
  PcapLibrary library;
  if (!resolve(handle, "pcap_open_dead", library.open_dead) ||
      !resolve(handle, "pcap_geterr", library.geterr) ||
      !resolve(handle, "pcap_close", library.close) ||
      !resolve(handle, "pcap_dump_open", library.dump_open) ||
      !resolve(handle, "pcap_dump", library.dump) ||
      !resolve(handle, "pcap_dump_file", library.dump_file) ||
      !resolve(handle, "pcap_dump_flush", library.dump_flush) ||
      !resolve(handle, "pcap_dump_close", library.dump_close)) {
    std::string reason = last_dl_error();
    ::dlclose(handle);
    return missing(reason);
  }
  return library;
}

cfg::Result<const PcapLibrary*> pcap_library() {
  // A function-local static: initialised once, by the first caller, while others wait.
  static const cfg::Result<PcapLibrary> loaded = load_pcap_library(CANOPEN_PCAP_SONAME);
  if (!loaded) return loaded.error();
  return &loaded.value();
}

}  // namespace nmt::detail
