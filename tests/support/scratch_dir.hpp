// A directory of one test's own, removed at its end. Its name carries the suite, the test and
// the process, so tests that CTest runs side by side (-j) never share one (a shared fixed name
// made two DcfgenVectors tests copy into and delete each other's files).
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

namespace test_support {

class ScratchDir {
 public:
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const std::string test = info != nullptr
                                 ? std::string(info->test_suite_name()) + "_" + info->name()
                                 : std::string("no_test");
    path_ = std::filesystem::temp_directory_path() /
            ("canopen_" + test + "_" + std::to_string(::getpid()));
    // A parameterised test's name holds '/'.
    std::string name = path_.filename().string();
    std::replace(name.begin(), name.end(), '/', '_');
    path_.replace_filename(name);
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::string str() const { return path_.string(); }
  /// The path of `name` inside the directory.
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }
  /// Names of the files in the directory (hidden ones too), sorted.
  std::vector<std::string> files() const {
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(path_)) {
      names.push_back(e.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }

 private:
  std::filesystem::path path_;
};

}  // namespace test_support
