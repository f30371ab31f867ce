// The configuration manager's store (cfg/config_manager.hpp): putting 127 concise DCFs of 100
// entries each into a store directory (each put a temporary file, fsync, rename, fsync of the
// directory), opening that directory again, the download plans of all 127 nodes, and the heap
// the manager takes holding the 127 streams.
//   cmake -S . -B build-bench -DCMAKE_BUILD_TYPE=Release -DCANOPEN_BUILD_TESTS=OFF
//   cmake --build build-bench --target bench_config_store && build-bench/bench/bench_config_store
// The directory is under $TMPDIR (else /tmp): fsync costs what that file system makes it cost.
#include <benchmark/benchmark.h>
#include <malloc.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cfg/config_manager.hpp"

namespace {

namespace fs = std::filesystem;

constexpr unsigned kNodes = 127;
constexpr unsigned kEntries = 100;

/// A node's concise DCF: 100 entries of 1, 2 and 4 bytes, different per node.
std::vector<std::uint8_t> concise_of(unsigned node) {
  std::vector<cfg::ObjectWrite> writes;
  for (unsigned i = 0; i < kEntries; ++i) {
    const std::size_t size = i % 3 == 0 ? 1 : i % 3 == 1 ? 2 : 4;
    std::vector<std::uint8_t> data(size);
    for (std::size_t b = 0; b < size; ++b) data[b] = static_cast<std::uint8_t>(node + i + b);
    writes.push_back({static_cast<std::uint16_t>(0x2000 + i / 16),
                      static_cast<std::uint8_t>(1 + i % 16), std::move(data)});
  }
  return cfg::encode_concise_dcf(writes);
}

const std::vector<std::vector<std::uint8_t>>& streams() {
  static const auto all = [] {
    std::vector<std::vector<std::uint8_t>> out;
    for (unsigned node = 1; node <= kNodes; ++node) out.push_back(concise_of(node));
    return out;
  }();
  return all;
}

std::size_t stream_bytes() {
  std::size_t total = 0;
  for (const auto& s : streams()) total += s.size();
  return total;
}

fs::path store_dir(const std::string& name) {
  return fs::temp_directory_path() /
         ("bench-config-store-" + name + "-" + std::to_string(getpid()));
}

void put_all(cfg::ConfigManager& manager) {
  for (unsigned node = 1; node <= kNodes; ++node) {
    if (!manager.put_concise(*cfg::NodeId::from(node), streams()[node - 1])) std::abort();
  }
}

/// A manager on a fresh directory; nullopt (and the benchmark skipped) when it cannot open.
std::optional<cfg::ConfigManager> open_fresh(benchmark::State& state, const fs::path& dir) {
  fs::remove_all(dir);
  auto manager = cfg::ConfigManager::open(dir.string());
  if (!manager) {
    state.SkipWithError(manager.error().message.c_str());
    return std::nullopt;
  }
  return std::move(*manager);
}

// 127 puts into the store directory, each durable before the next.
void BM_Put127ConciseDcfs(benchmark::State& state) {
  const fs::path dir = store_dir("put");
  auto manager = open_fresh(state, dir);
  if (!manager) return;
  for (auto _ : state) put_all(*manager);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * stream_bytes()));
  state.counters["puts/s"] = benchmark::Counter(static_cast<double>(state.iterations() * kNodes),
                                                benchmark::Counter::kIsRate);
  fs::remove_all(dir);
}
BENCHMARK(BM_Put127ConciseDcfs)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(5);

// The same into a manager without a directory: the cost of the store's own work.
void BM_Put127ConciseDcfsInMemory(benchmark::State& state) {
  cfg::ConfigManager manager;
  for (auto _ : state) put_all(manager);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * stream_bytes()));
}
BENCHMARK(BM_Put127ConciseDcfsInMemory)->Unit(benchmark::kMicrosecond);

// Opening a directory of 127 entries: read, CRC-32, decode every stream.
void BM_Open127ConciseDcfs(benchmark::State& state) {
  const fs::path dir = store_dir("open");
  {
    auto manager = open_fresh(state, dir);
    if (!manager) return;
    put_all(*manager);
  }
  for (auto _ : state) {
    auto manager = cfg::ConfigManager::open(dir.string());
    benchmark::DoNotOptimize(manager.ok());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * stream_bytes()));
  fs::remove_all(dir);
}
BENCHMARK(BM_Open127ConciseDcfs)->Unit(benchmark::kMillisecond);

// The download plans of all 127 nodes (decode, PDO-safe order, 1020h/1010h tail).
void BM_Plan127Nodes(benchmark::State& state) {
  cfg::ConfigManager manager;
  put_all(manager);
  for (unsigned node = 1; node <= kNodes; ++node) {
    (void)manager.set_expected_stamp(*cfg::NodeId::from(node), {14000, node});
  }
  for (auto _ : state) {
    for (unsigned node = 1; node <= kNodes; ++node) {
      auto plan = manager.download_plan(*cfg::NodeId::from(node));
      benchmark::DoNotOptimize(plan.ok());
    }
  }
}
BENCHMARK(BM_Plan127Nodes)->Unit(benchmark::kMicrosecond);

// Heap in use (glibc mallinfo2) by a manager holding the 127 streams, against their size.
void BM_MemoryOf127ConciseDcfs(benchmark::State& state) {
  std::size_t heap = 0;
  std::size_t stored = 0;
  for (auto _ : state) {
    const std::size_t before = mallinfo2().uordblks;
    std::optional<cfg::ConfigManager> manager;
    manager.emplace();
    put_all(*manager);
    heap = mallinfo2().uordblks - before;
    stored = manager->stored_bytes();
    manager.reset();
  }
  state.counters["heap_bytes"] = static_cast<double>(heap);
  state.counters["stored_bytes"] = static_cast<double>(stored);
  state.counters["stream_bytes"] = static_cast<double>(stream_bytes());
}
BENCHMARK(BM_MemoryOf127ConciseDcfs)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
