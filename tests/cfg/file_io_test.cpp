// cfg::read_file: the one way tools read a file, in one piece (whole-process speed).
// Bytes must come back exactly, whatever the file is: mapped regular files, pipes, empty files.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "cfg/device_file.hpp"

namespace cfg {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class ReadFile : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "read_file.XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string write(const std::string& name, const std::string& bytes) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary)
        .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
  }
  fs::path dir_;
};

// Every byte value, CR/LF mixes and a NUL: nothing is translated.
TEST_F(ReadFile, GivesTheBytesOfARegularFileExactly) {
  std::string bytes;
  for (int i = 0; i < 256; ++i) bytes += static_cast<char>(i);
  bytes += "[1000]\r\nParameterName=x\n\r\n";
  bytes = bytes + bytes + bytes;
  auto text = read_file(write("all.bin", bytes));
  ASSERT_TRUE(text.ok()) << text.error().message;
  EXPECT_EQ(text->view(), bytes);
  EXPECT_EQ(text->size(), bytes.size());
}

TEST_F(ReadFile, EmptyFileIsEmptyText) {
  auto text = read_file(write("empty.dcf", ""));
  ASSERT_TRUE(text.ok()) << text.error().message;
  EXPECT_TRUE(text->view().empty());
}

// A pipe has no size: the reader grows its buffer until end of file (more than its first
// 64 KiB here).
TEST_F(ReadFile, ReadsAPipeToItsEnd) {
  std::string bytes(200 * 1024, 'x');
  for (std::size_t i = 0; i < bytes.size(); i += 97) bytes[i] = '\n';
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(fds[0]);
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fds[1], bytes.data() + done, bytes.size() - done);
      if (n <= 0) ::_exit(1);
      done += static_cast<std::size_t>(n);
    }
    ::_exit(0);
  }
  ::close(fds[1]);
  auto text = read_file(fds[0]);
  ::close(fds[0]);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(text.ok()) << text.error().message;
  EXPECT_EQ(text->view(), bytes);
}

TEST_F(ReadFile, MissingFileAndDirectoryAreErrorsThatSayWhy) {
  auto missing = read_file((dir_ / "nope.dcf").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_THAT(missing.error().message, HasSubstr("cannot open the file: No such file"));
  auto directory = read_file(dir_.string());
  ASSERT_FALSE(directory.ok());
  EXPECT_EQ(directory.error().message, "is a directory");
}

// Moving the text keeps the bytes; release() gives them back and leaves it empty.
TEST_F(ReadFile, TextMovesAndReleases) {
  auto text = read_file(write("a.dcf", "[FileInfo]\r\n"));
  ASSERT_TRUE(text.ok());
  FileText moved = std::move(*text);
  EXPECT_EQ(moved.view(), "[FileInfo]\r\n");
  moved.release();
  EXPECT_TRUE(moved.view().empty());
}

// read_device_file goes through read_file: the same model as parsing the text.
TEST_F(ReadFile, ReadDeviceFileParsesWhatReadFileGives) {
  const std::string dcf =
      "[DeviceInfo]\r\nVendorName=V\r\n[1017]\r\nParameterName=Producer heartbeat time\r\n"
      "ObjectType=0x7\r\nDataType=0x0006\r\nAccessType=rw\r\nDefaultValue=1000\r\n";
  auto from_file = read_device_file(write("d.dcf", dcf));
  auto from_text = parse_device_description(dcf);
  ASSERT_TRUE(from_file.device.has_value());
  ASSERT_TRUE(from_text.device.has_value());
  EXPECT_EQ(*from_file.device, *from_text.device);
  EXPECT_EQ(from_file.device->sub(0x1017, 0)->default_value, "1000");
  EXPECT_EQ(from_file.device->sub(0x1017, 0)->default_value_line, 8);  // its own key's line
}

}  // namespace
}  // namespace cfg
