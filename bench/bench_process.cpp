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
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "generated_dcf.hpp"
#include "process_runner.hpp"

namespace {

namespace fs = std::filesystem;
using bench::median;
using bench::ProcessSample;
using bench::run_process;

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

Figures summarize(const std::vector<ProcessSample>& samples) {
  std::vector<double> ms;
  std::vector<double> cpu;
  std::vector<double> rss;
  for (const auto& s : samples) {
    ms.push_back(s.wall_ms);
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
    std::vector<ProcessSample> a;
    std::vector<ProcessSample> b;
    run_process(ours);  // warm-up: page cache, dynamic loader
    if (!baseline.empty()) run_process(theirs);
    for (int r = 0; r < runs; ++r) {
      a.push_back(run_process(ours));
      if (!baseline.empty()) b.push_back(run_process(theirs));
    }
    // cfgmgr check exits 1 when the file has errors; the generated file has none.
    for (const auto& s : a) failures += s.exit_code == 0 ? 0 : 1;
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
