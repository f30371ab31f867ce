// Reading a whole file in one piece (device_file.hpp).
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "cfg/device_file.hpp"

namespace cfg {

Result<std::string> read_file(int fd) {
  struct stat st {};
  const bool sized = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0;
  // A regular file's size is known: one allocation and usually one read (the +1 lets the read
  // that sees end of file fit without growing). Pipes and /proc files report no size, so the
  // buffer grows while data keeps coming.
  std::string text(sized ? static_cast<std::size_t>(st.st_size) + 1 : std::size_t{64 * 1024}, '\0');
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
  return text;
}

Result<std::string> read_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Error{std::string("cannot open the file: ") + std::strerror(errno)};
  struct stat st {};
  if (::fstat(fd, &st) == 0 && S_ISDIR(st.st_mode)) {
    ::close(fd);
    return Error{"is a directory"};
  }
  Result<std::string> text = read_file(fd);
  ::close(fd);
  return text;
}

}  // namespace cfg
