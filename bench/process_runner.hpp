// What the whole-process benchmarks (bench_process, bench_push) share: run a program to its exit
// and measure it as a user would (wall time from spawn to reap, CPU time and peak RSS of the
// child from wait4), and the median of the runs.
#pragma once

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

extern char** environ;  // NOLINT(readability-redundant-declaration): POSIX, for posix_spawn

namespace bench {

/// One run of a process.
struct ProcessSample {
  double wall_ms = 0;    ///< from before posix_spawn to after wait4
  double cpu_ms = 0;     ///< user + system time of the child (rusage)
  long max_rss_kib = 0;  ///< peak resident set size of the child (ru_maxrss, KiB on Linux)
  int exit_code = -1;    ///< the exit status, -1 when a signal ended it
};

/// Runs `argv` (argv[0] a path, no PATH search) with stdout and stderr to /dev/null and waits
/// for it. A benchmark cannot go on without its program: a failed spawn or wait ends this
/// process with exit 2.
inline ProcessSample run_process(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  args.reserve(argv.size() + 1);
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  ProcessSample s;
  const auto start = std::chrono::steady_clock::now();
  pid_t pid = 0;
  if (posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ) != 0) {
    std::perror(args[0]);
    std::exit(2);
  }
  int status = 0;
  struct rusage usage {};
  if (wait4(pid, &status, 0, &usage) < 0) {
    std::perror("wait4");
    std::exit(2);
  }
  const auto end = std::chrono::steady_clock::now();
  posix_spawn_file_actions_destroy(&actions);
  s.wall_ms = std::chrono::duration<double, std::milli>(end - start).count();
  s.max_rss_kib = usage.ru_maxrss;
  auto to_ms = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_usec) / 1e3;
  };
  s.cpu_ms = to_ms(usage.ru_utime) + to_ms(usage.ru_stime);
  s.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return s;
}

/// The median (the mean of the middle two for an even count); 0 for none.
inline double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

}  // namespace bench
