// cfg::read_file: the one way tools read a file, in one piece (whole-process speed).
// Bytes must come back exactly, whatever the file is: mapped regular files, pipes, empty files.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
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

// The resident size (Rss, KiB) of this process's mapping that holds `address`, from
// /proc/self/smaps; nullopt where there is no such file.
std::optional<long> resident_kib_of_mapping(const void* address) {
  std::ifstream smaps("/proc/self/smaps");
  if (!smaps) return std::nullopt;
  const auto at = reinterpret_cast<std::uintptr_t>(address);
  bool inside = false;
  std::string line;
  while (std::getline(smaps, line)) {
    unsigned long begin = 0;
    unsigned long end = 0;
    if (std::sscanf(line.c_str(), "%lx-%lx ", &begin, &end) == 2) {
      inside = at >= begin && at < end;
    } else if (inside && line.rfind("Rss:", 0) == 0) {
      return std::stol(line.substr(4));
    }
  }
  return std::nullopt;
}

// Pages given back leave the process's resident set (what a tool's peak memory counts) but
// not the text: read again, every byte is there.
TEST_F(ReadFile, ReleasedPagesLeaveTheResidentSetAndStayReadable) {
  std::string bytes(64 * 4096 + 100, '\0');
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>('A' + i % 26);
  auto text = read_file(write("pages.dcf", bytes));
  ASSERT_TRUE(text.ok()) << text.error().message;
  const auto before = resident_kib_of_mapping(text->view().data());
  if (!before) GTEST_SKIP() << "no /proc/self/smaps";
  EXPECT_GE(*before, 64 * 4);  // mapped with its pages brought in

  text->release_pages(0, 10 * 4096 + 5);  // pages 0..9; page 10 holds the end, it stays
  text->release_pages(10 * 4096 + 5, text->size());
  EXPECT_EQ(resident_kib_of_mapping(text->view().data()), 0);
  EXPECT_EQ(text->view(), bytes);
}

// Read into memory (a pipe, standard input), there are no file pages to give back: nothing
// changes.
TEST_F(ReadFile, ReleasingPagesOfATextInMemoryChangesNothing) {
  FileText text(std::string(10000, 'x'));
  text.release_pages(0, text.size());
  EXPECT_EQ(text.view(), std::string(10000, 'x'));
}

// Parsing a FileText gives its pages back as the reader passes them (256 KiB at a time), and
// what the reader looks up in the file after its last line (the [xxxxName]/[xxxxValue] texts of
// a CompactSubObj object, [Comments]) is read back from the file: the model and diagnostics are
// those of parsing the text itself.
TEST_F(ReadFile, ParsingAFileTextGivesTheModelOfItsText) {
  std::string dcf =
      "[DeviceInfo]\r\nVendorName=V\r\n[Comments]\r\nLines=1\r\nLine1=first of the file\r\n"
      "[1016]\r\nParameterName=Consumer heartbeat time\r\nObjectType=0x8\r\n"
      "DataType=0x0007\r\nAccessType=rw\r\nDefaultValue=0\r\nCompactSubObj=3\r\n"
      "[1016Name]\r\nNrOfEntries=1\r\n1=Heartbeat of node 2\r\n"
      "[1016Value]\r\nNrOfEntries=1\r\n1=0x000203E8\r\n";
  for (int i = 0; dcf.size() < 600 * 1024; ++i) {
    char section[80];
    std::snprintf(section, sizeof section, "[%04X]\r\nParameterName=Object %d\r\n", 0x2000 + i, i);
    dcf += section;
    dcf += "ObjectType=0x7\r\nDataType=0x0007\r\nAccessType=rw\r\nDefaultValue=7\r\n";
  }
  auto file = read_file(write("big.dcf", dcf));
  ASSERT_TRUE(file.ok()) << file.error().message;
  const ReadOptions options{ReadMode::Strict, "big.dcf"};
  auto from_file = parse_device_description(*file, options);
  auto from_text = parse_device_description(std::string_view(dcf), options);
  ASSERT_TRUE(from_file.device.has_value());
  ASSERT_TRUE(from_text.device.has_value());
  EXPECT_EQ(*from_file.device, *from_text.device);
  EXPECT_EQ(from_file.diagnostics.format(), from_text.diagnostics.format());
  EXPECT_EQ(from_file.device->sub(0x1016, 1)->name, "Heartbeat of node 2");
  EXPECT_EQ(from_file.device->sub(0x1016, 1)->parameter_value, "0x000203E8");
  EXPECT_EQ(file->view(), dcf);
}

// A file the reader does not look back into is not resident at all once read: the pages are
// given back behind the reader as it goes, the last ones after the last line.
TEST_F(ReadFile, ParsingAFileTextLeavesNoneOfItResident) {
  std::string dcf = "[DeviceInfo]\r\nVendorName=V\r\n";
  for (int i = 0; dcf.size() < 600 * 1024; ++i) {
    char section[80];
    std::snprintf(section, sizeof section, "[%04X]\r\nParameterName=Object %d\r\n", 0x2000 + i, i);
    dcf += section;
    dcf += "ObjectType=0x7\r\nDataType=0x0007\r\nAccessType=rw\r\nDefaultValue=7\r\n";
  }
  auto file = read_file(write("plain.dcf", dcf));
  ASSERT_TRUE(file.ok()) << file.error().message;
  const auto before = resident_kib_of_mapping(file->view().data());
  if (!before) GTEST_SKIP() << "no /proc/self/smaps";
  EXPECT_GE(*before, 600);
  auto read = parse_device_description(*file, ReadOptions{ReadMode::Tolerant, "plain.dcf"});
  ASSERT_TRUE(read.device.has_value());
  EXPECT_EQ(read.device->sub(0x2005, 0)->name, "Object 5");
  EXPECT_EQ(resident_kib_of_mapping(file->view().data()), 0);
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
