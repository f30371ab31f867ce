// The tools as a user measures them: whole processes, start to exit, on the generated DCF of
// bench_dcf2concise (generated_dcf.hpp, 2.95 MB). Each command runs `--runs` times (after one
// warm-up run); the figure is the median wall time, with the peak resident set size of the
// process (getrusage ru_maxrss: code, libraries, the file and the model). With --baseline DIR
// (a build directory of another commit, with tools/dcf2concise and tools/cfgmgr in it) the same
// commands of that build run interleaved with ours, so both see the same machine load, and the
// ratio baseline / ours is printed.
//
//   cmake --build build --target bench_process
//   build/bench/bench_process --runs 21 --baseline /path/to/baseline/build
//   build/bench/bench_process --write-input /tmp/big.dcf   # only the file, for perf/heaptrack
//
// Not a Google Benchmark: the unit of work is a process, and the runner must see its exit.
#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "generated_dcf.hpp"

extern char** environ;  // NOLINT(readability-redundant-declaration): POSIX, for posix_spawn

namespace {

namespace fs = std::filesystem;

struct Sample {
  double ms = 0;
  double cpu_ms = 0;  // user + system time of the child
  long max_rss_kib = 0;
  int status = 0;
};

// Runs argv with stdout/stderr to /dev/null; wall time from before the spawn to after the reap.
Sample run_once(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  args.reserve(argv.size() + 1);
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  Sample s;
  const auto start = std::chrono::steady_clock::now();
  pid_t pid = 0;
  if (posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ) != 0) {
    std::perror(args[0]);
    std::exit(2);
  }
  struct rusage usage {};
  if (wait4(pid, &s.status, 0, &usage) < 0) {
    std::perror("wait4");
    std::exit(2);
  }
  const auto end = std::chrono::steady_clock::now();
  posix_spawn_file_actions_destroy(&actions);
  s.ms = std::chrono::duration<double, std::milli>(end - start).count();
  s.max_rss_kib = usage.ru_maxrss;
  auto to_ms = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_usec) / 1e3;
  };
  s.cpu_ms = to_ms(usage.ru_utime) + to_ms(usage.ru_stime);
  return s;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

struct Command {
  std::string label;
  std::vector<std::string> args;  // after the program
  std::string tool;               // "dcf2concise" or "cfgmgr"
};

struct Figures {
  double ms = 0;
  double cpu_ms = 0;
  double rss_mib = 0;
};

Figures summarize(const std::vector<Sample>& samples) {
  std::vector<double> ms;
  std::vector<double> cpu;
  std::vector<double> rss;
  for (const auto& s : samples) {
    ms.push_back(s.ms);
    cpu.push_back(s.cpu_ms);
    rss.push_back(static_cast<double>(s.max_rss_kib) / 1024.0);
  }
  return {median(ms), median(cpu), median(rss)};
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 15;
  std::string baseline;
  std::string write_input;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--runs" && i + 1 < argc) {
      runs = std::max(1, static_cast<int>(std::strtol(argv[++i], nullptr, 10)));
    } else if (a == "--baseline" && i + 1 < argc) {
      baseline = argv[++i];
    } else if (a == "--write-input" && i + 1 < argc) {
      write_input = argv[++i];
    } else {
      std::cerr << "usage: bench_process [--runs N] [--baseline BUILD_DIR] [--write-input FILE]\n";
      return 2;
    }
  }

  if (!write_input.empty()) {
    const std::string text = bench::generated_big_dcf();
    std::ofstream out(write_input, std::ios::binary);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    return out ? 0 : 2;
  }
  std::string dir_template = (fs::temp_directory_path() / "bench_process.XXXXXX").string();
  if (mkdtemp(dir_template.data()) == nullptr) {
    std::perror("mkdtemp");
    return 2;
  }
  const fs::path dir = dir_template;
  const fs::path dcf = dir / "big.dcf";
  const std::string text = bench::generated_big_dcf();
  std::ofstream(dcf, std::ios::binary)
      .write(text.data(), static_cast<std::streamsize>(text.size()));
  const double mb = static_cast<double>(text.size()) / 1e6;

  const std::vector<Command> commands = {
      {"dcf2concise big.dcf -o out.bin",
       {dcf.string(), "-o", (dir / "out.bin").string()},
       "dcf2concise"},
      {"cfgmgr check big.dcf", {"check", dcf.string()}, "cfgmgr"},
      {"cfgmgr fmt big.dcf -o out.dcf",
       {"fmt", dcf.string(), "-o", (dir / "out.dcf").string()},
       "cfgmgr"},
  };
  auto program = [](const std::string& build, const std::string& tool) {
    return build.empty() ? std::string(tool == "cfgmgr" ? CANOPEN_CFGMGR : CANOPEN_DCF2CONCISE)
                         : (fs::path(build) / "tools" / tool).string();
  };

  std::printf("input: generated DCF, %.2f MB; %d runs each, median; %s\n\n", mb, runs,
              baseline.empty() ? "no baseline" : ("baseline " + baseline).c_str());
  std::printf("| command | wall | throughput | CPU | peak RSS |%s\n",
              baseline.empty() ? "" : " baseline wall | baseline CPU | baseline RSS | speed-up |");
  std::printf("| --- | --- | --- | --- | --- |%s\n",
              baseline.empty() ? "" : " --- | --- | --- | --- |");
  int failures = 0;
  for (const auto& c : commands) {
    std::vector<std::string> ours = c.args;
    ours.insert(ours.begin(), program("", c.tool));
    std::vector<std::string> theirs = c.args;
    theirs.insert(theirs.begin(), program(baseline, c.tool));
    std::vector<Sample> a;
    std::vector<Sample> b;
    run_once(ours);  // warm-up: page cache, dynamic loader
    if (!baseline.empty()) run_once(theirs);
    for (int r = 0; r < runs; ++r) {
      a.push_back(run_once(ours));
      if (!baseline.empty()) b.push_back(run_once(theirs));
    }
    // cfgmgr check exits 1 when the file has errors; the generated file has none.
    for (const auto& s : a) failures += (WIFEXITED(s.status) && WEXITSTATUS(s.status) == 0) ? 0 : 1;
    const Figures fa = summarize(a);
    std::printf("| `%s` | %.1f ms | %.0f MB/s | %.1f ms | %.1f MiB |", c.label.c_str(), fa.ms,
                mb / (fa.ms / 1000.0), fa.cpu_ms, fa.rss_mib);
    if (!baseline.empty()) {
      const Figures fb = summarize(b);
      std::printf(" %.1f ms | %.1f ms | %.1f MiB | **%.2fx** wall, %.2fx CPU |", fb.ms, fb.cpu_ms,
                  fb.rss_mib, fb.ms / fa.ms, fb.cpu_ms / fa.cpu_ms);
    }
    std::printf("\n");
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
  if (failures > 0) {
    std::fprintf(stderr, "bench_process: %d runs did not exit 0\n", failures);
    return 1;
  }
  return 0;
}
