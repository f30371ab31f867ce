// libFuzzer target: arbitrary bytes as a lely dcfgen / ros2_canopen bus.yml (cfg/bus_yml.hpp),
// read beside copies of samples/drive.eds and samples/io_module.eds (so `dcf: drive.eds` finds
// a device). Checks: no crash or hang; every diagnostic of the bus.yml names a line of it (0
// for the file as a whole); a network read without errors has node-IDs that are unique, in
// 1..127 and not the master's, and writes for each node.
// Seeds: tests/fuzz/seeds/bus_yml/.
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include "cfg/bus_yml.hpp"

namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const char* what) {
  std::fprintf(stderr, "fuzz_bus_yml: %s\n", what);
  std::abort();
}

// A directory of this process with the two device files, made once.
const fs::path& work_dir() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("fuzz_bus_yml." + std::to_string(getpid()));
    fs::create_directories(d);
    const fs::path samples = fs::path(CANOPEN_FUZZ_DATA_DIR) / ".." / ".." / "samples";
    for (const char* name : {"drive.eds", "io_module.eds"}) {
      fs::copy_file(samples / name, d / name, fs::copy_options::overwrite_existing);
    }
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = (work_dir() / "bus.yml").string();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  const int lines = static_cast<int>(std::count(data, data + size, '\n')) + 1;
  const cfg::NetworkLoad load = cfg::load_bus_yml(path);
  for (const auto& d : load.diagnostics.items()) {
    if (d.file == path && (d.line < 0 || d.line > lines + 1)) fail("a diagnostic past the file");
  }
  if (!load.ok()) return 0;
  std::set<unsigned> seen;
  for (const auto& node : load.network->nodes) {
    const unsigned id = node.node_id.value();
    if (id < 1 || id > 127) fail("a node-ID outside 1..127");
    if (!seen.insert(id).second) fail("two nodes with one node-ID");
    if (load.network->master_node_id && load.network->master_node_id->value() == id) {
      fail("a node with the master's node-ID");
    }
    if (!node.dcf) fail("a node without its DCF");
  }
  return 0;
}
