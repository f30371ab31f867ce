// Reading a whole file in one piece (device_file.hpp).
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <string>
#include <utility>

#include "cfg/device_file.hpp"

namespace cfg {

FileText::FileText(std::string bytes) : buffer_(std::move(bytes)) {}

FileText::FileText(FileText&& other) noexcept
    : mapped_(std::exchange(other.mapped_, nullptr)),
      mapped_size_(std::exchange(other.mapped_size_, 0)),
      buffer_(std::move(other.buffer_)) {}

FileText& FileText::operator=(FileText&& other) noexcept {
  if (this != &other) {
    release();
    mapped_ = std::exchange(other.mapped_, nullptr);
    mapped_size_ = std::exchange(other.mapped_size_, 0);
    buffer_ = std::move(other.buffer_);
  }
  return *this;
}

FileText::~FileText() {
  release();
}

void FileText::release() {
  if (mapped_ != nullptr) ::munmap(const_cast<char*>(mapped_), mapped_size_);
  mapped_ = nullptr;
  mapped_size_ = 0;
  std::string().swap(buffer_);
}

void FileText::release_pages(std::size_t begin, std::size_t end) const {
  if (mapped_ == nullptr) return;
  static const auto page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  begin -= begin % page;
  // To the end: the last page too, though the file ends inside it.
  end = end >= mapped_size_ ? mapped_size_ + (page - mapped_size_ % page) % page : end - end % page;
  // The mapping is read-only and private, so none of its pages was ever copied on write: each
  // one dropped is the file's, and reading it again maps the cached page back.
  if (end > begin) ::madvise(const_cast<char*>(mapped_) + begin, end - begin, MADV_DONTNEED);
}

Result<FileText> read_file(int fd) {
  struct stat st {};
  const bool regular = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
  if (regular && st.st_size > 0) {
    // Mapped, with the pages brought in at once (MAP_POPULATE): no copy, no zeroed heap pages,
    // one page-table fill instead of a fault per page. The text is the file's page cache.
    const auto size = static_cast<std::size_t>(st.st_size);
    void* p = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (p != MAP_FAILED) {
      FileText text;
      text.mapped_ = static_cast<const char*>(p);
      text.mapped_size_ = size;
      return text;
    }
    // Some file systems cannot map: read instead.
  }
  // Pipes and /proc files report no size, so the buffer grows while data keeps coming; a
  // regular file that could not be mapped is read in one piece (the +1 lets the read that sees
  // end of file fit without growing).
  std::string text(
      regular && st.st_size > 0 ? static_cast<std::size_t>(st.st_size) + 1 : std::size_t{64} * 1024,
      '\0');
  std::size_t used = 0;
  for (;;) {
    if (used == text.size()) text.resize(text.size() * 2);
    const ssize_t n = ::read(fd, text.data() + used, text.size() - used);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return Error{std::string("cannot read the file: ") + std::strerror(errno)};
    if (n == 0) break;
    used += static_cast<std::size_t>(n);
  }
  text.resize(used);
  return FileText(std::move(text));
}

Result<FileText> read_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Error{std::string("cannot open the file: ") + std::strerror(errno)};
  struct stat st {};
  if (::fstat(fd, &st) == 0 && S_ISDIR(st.st_mode)) {
    ::close(fd);
    return Error{"is a directory"};
  }
  Result<FileText> text = read_file(fd);
  ::close(fd);  // a mapping stays valid after close
  return text;
}

}  // namespace cfg
