// Where the tests find the project's files: the directories are read at run time from
// test_paths.txt, which tests/CMakeLists.txt writes beside the test programs (one NAME=PATH a
// line). No absolute path is compiled into a test object, so the compile lines are the same in
// every checkout and ccache (CCACHE_BASEDIR) shares the test objects between checkouts.
//   CANOPEN_TEST_DATA_DIR  tests/data
//   CANOPEN_SAMPLES_DIR    samples
//   CANOPEN_SCHEMA_DIR     schemas
//   CANOPEN_CORPUS_DIR     the vendor corpus, ../shared/corpus beside the checkout (may be absent)
//   CANOPEN_TOOLS_DIR      the directory of the built cfgmgr and dcf2concise
// Each is a `const std::string&`, absolute as before.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

namespace test_paths {

/// The value of `name` in test_paths.txt beside the running program; aborts with a message
/// when the file or the name is missing (no test can run without it).
inline const std::string& get(const std::string& name) {
  static const std::map<std::string, std::string> paths = [] {
    const auto file =
        std::filesystem::read_symlink("/proc/self/exe").parent_path() / "test_paths.txt";
    std::map<std::string, std::string> read;
    std::ifstream in(file);
    for (std::string line; std::getline(in, line);) {
      const auto equals = line.find('=');
      if (equals != std::string::npos) read[line.substr(0, equals)] = line.substr(equals + 1);
    }
    if (read.empty()) {
      std::fprintf(stderr, "%s: missing or empty (tests/CMakeLists.txt writes it)\n", file.c_str());
      std::abort();
    }
    return read;
  }();
  const auto it = paths.find(name);
  if (it == paths.end()) {
    std::fprintf(stderr, "test_paths.txt has no %s\n", name.c_str());
    std::abort();
  }
  return it->second;
}

}  // namespace test_paths

#define CANOPEN_TEST_DATA_DIR (::test_paths::get("CANOPEN_TEST_DATA_DIR"))
#define CANOPEN_SAMPLES_DIR (::test_paths::get("CANOPEN_SAMPLES_DIR"))
#define CANOPEN_SCHEMA_DIR (::test_paths::get("CANOPEN_SCHEMA_DIR"))
#define CANOPEN_CORPUS_DIR (::test_paths::get("CANOPEN_CORPUS_DIR"))
#define CANOPEN_TOOLS_DIR (::test_paths::get("CANOPEN_TOOLS_DIR"))
