// A test that cannot run because something it needs is missing here (the corpus in ../shared,
// python-can, tshark, can-utils, a network namespace, /dev/full, the samples, vcan in the VM
// guest) says so with PREREQUISITE_MISSING(why...): it skips on a developer's machine, and fails
// under CI=true, where tools/install-deps.sh has installed everything and a skip would hide a tier
// that never ran. The message names what is missing; the parts are streamed together.
//
// Skips that depend on a property of the device or kernel the test cannot control (a kernel that
// refuses to write an error frame, an interface whose transmit queue cannot fill) stay plain
// GTEST_SKIP() with a comment saying why; so do tests that run in another ctest test (the
// multicast tests outside their network namespace). tests/support/prerequisite.sh is the same for
// the scripts ctest runs.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <sstream>
#include <string>
#include <string_view>

namespace test_support {

/// True when CI=true: a missing prerequisite is then a failure, not a skip.
inline bool prerequisites_required() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && std::string_view(ci) == "true";
}

template <typename... Parts>
std::string prerequisite_text(const Parts&... parts) {
  std::ostringstream out;
  (out << ... << parts);
  return out.str();
}

}  // namespace test_support

/// Skips the current test (fails it under CI=true) because a prerequisite is missing. Like
/// GTEST_SKIP(), returns from the current function, so use it in the test body or SetUp().
#define PREREQUISITE_MISSING(...)                                                         \
  do {                                                                                    \
    const std::string prerequisite_why_ = ::test_support::prerequisite_text(__VA_ARGS__); \
    if (::test_support::prerequisites_required()) {                                       \
      GTEST_FAIL() << "CI=true: prerequisite missing: " << prerequisite_why_;             \
    }                                                                                     \
    GTEST_SKIP() << prerequisite_why_;                                                    \
  } while (0)
