// What our INI scanner costs against the library the product's first plan named: Debian's inih
// (libinih-dev), both only splitting the generated 2.95 MB DCF of bench_process into key=value
// pairs and counting them. The reader itself (values, model) is bench_parse's and
// bench_process's. Built when pkg-config finds inih (tools/install-deps.sh installs it).
//
// Run: cmake --build build --target bench_ini_vs_inih && build/bench/bench_ini_vs_inih
//
// inih's ini_parse_string sees the same text; its lines are all shorter than its 200-byte
// buffer, so both count the same pairs (checked below), which makes the times comparable.
#include <benchmark/benchmark.h>
#include <ini.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "generated_dcf.hpp"
#include "ini_scanner.hpp"

namespace {

const std::string& text() {
  static const std::string t = bench::generated_big_dcf();
  return t;
}

class CountingSink final : public cfg::detail::IniSink {
 public:
  void on_section(int, std::string_view, std::string_view, bool) override { ++sections; }
  void on_key(int, std::string_view, std::string_view) override { ++keys; }
  void on_comment(int, char) override {}
  void on_junk(int, std::string_view) override {}
  long sections = 0;
  long keys = 0;
};

long scanner_keys() {
  CountingSink sink;
  cfg::detail::scan_ini(text(), sink);
  return sink.keys;
}

int count_pair(void* user, const char*, const char*, const char*) {
  ++*static_cast<long*>(user);
  return 1;
}

long inih_keys() {
  long keys = 0;
  if (ini_parse_string(text().c_str(), count_pair, &keys) != 0) return -1;
  return keys;
}

void BM_OurScanner(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(scanner_keys());
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * text().size()));
}
BENCHMARK(BM_OurScanner)->Unit(benchmark::kMillisecond);

void BM_Inih(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(inih_keys());
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * text().size()));
}
BENCHMARK(BM_Inih)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  const long ours = scanner_keys();
  const long theirs = inih_keys();
  std::printf("key=value pairs: scanner %ld, inih %ld (%zu bytes)\n", ours, theirs, text().size());
  if (ours != theirs) {
    std::fprintf(stderr, "the two disagree on the pairs: the comparison would not be fair\n");
    return 1;
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
