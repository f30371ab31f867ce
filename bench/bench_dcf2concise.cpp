// dcf2concise end to end in-process: parse a DCF (CiA 306 reader), choose and order the writes
// (concise_writes_from_dcf, PDO rule of DSP 302 §6.2), encode the 1F22h stream; and the phases
// alone, and the streaming decoder. Inputs: a generated large DCF and the largest corpus DCF.
//   cmake -S . -B build-rel -DCMAKE_BUILD_TYPE=Release -DCANOPEN_BUILD_TESTS=OFF
//   cmake --build build-rel --target bench_dcf2concise && build-rel/bench/bench_dcf2concise
#include <benchmark/benchmark.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "generated_dcf.hpp"

namespace {

const std::string& generated() {
  static const std::string text = bench::generated_big_dcf();
  return text;
}

std::string largest_corpus_dcf_path() {
  namespace fs = std::filesystem;
  const fs::path corpus(CANOPEN_CORPUS_DIR);
  std::string best;
  std::uintmax_t best_size = 0;
  if (!fs::exists(corpus)) return best;
  for (const auto& e : fs::recursive_directory_iterator(corpus)) {
    if (e.path().extension() != ".dcf") continue;
    if (e.file_size() > best_size) {
      best_size = e.file_size();
      best = e.path().string();
    }
  }
  return best;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Parse + writes + encode, as dcf2concise does (file I/O aside).
void run_end_to_end(benchmark::State& state, const std::string& text,
                    cfg::ConciseSelection selection) {
  cfg::ConciseOptions options;
  options.selection = selection;
  options.node_id = 5;
  std::size_t entries = 0;
  std::size_t stream_size = 0;
  for (auto _ : state) {
    auto read = cfg::parse_device_description(text);
    cfg::Diagnostics diagnostics;
    auto writes = cfg::concise_writes_from_dcf(*read.device, options, diagnostics);
    if (!writes) {
      state.SkipWithError(diagnostics.format().c_str());
      return;
    }
    auto stream = cfg::encode_concise_dcf(*writes);
    entries = writes->size();
    stream_size = stream.size();
    benchmark::DoNotOptimize(stream.data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * text.size()));
  state.counters["dcf_bytes"] = static_cast<double>(text.size());
  state.counters["entries"] = static_cast<double>(entries);
  state.counters["stream_bytes"] = static_cast<double>(stream_size);
}

void BM_EndToEnd_Generated(benchmark::State& state) {
  run_end_to_end(state, generated(), cfg::ConciseSelection::Configured);
}
BENCHMARK(BM_EndToEnd_Generated)->Unit(benchmark::kMillisecond);

void BM_EndToEnd_Generated_ChangedOnly(benchmark::State& state) {
  run_end_to_end(state, generated(), cfg::ConciseSelection::ChangedOnly);
}
BENCHMARK(BM_EndToEnd_Generated_ChangedOnly)->Unit(benchmark::kMillisecond);

void BM_EndToEnd_LargestCorpusDcf(benchmark::State& state) {
  const std::string path = largest_corpus_dcf_path();
  if (path.empty()) {
    state.SkipWithError("corpus not found");
    return;
  }
  state.SetLabel(std::filesystem::path(path).filename().string() + ", WithDefaults");
  // Its ParameterValues are all empty, so WithDefaults is the selection that does work.
  run_end_to_end(state, read_text(path), cfg::ConciseSelection::WithDefaults);
}
BENCHMARK(BM_EndToEnd_LargestCorpusDcf)->Unit(benchmark::kMillisecond);

// The phases alone, on the generated DCF.
void BM_Phase_Parse(benchmark::State& state) {
  for (auto _ : state) {
    auto read = cfg::parse_device_description(generated());
    benchmark::DoNotOptimize(read.device->objects.size());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * generated().size()));
}
BENCHMARK(BM_Phase_Parse)->Unit(benchmark::kMillisecond);

void BM_Phase_Writes(benchmark::State& state) {
  const auto device = *cfg::parse_device_description(generated()).device;
  cfg::ConciseOptions options;
  for (auto _ : state) {
    cfg::Diagnostics diagnostics;
    auto writes = cfg::concise_writes_from_dcf(device, options, diagnostics);
    benchmark::DoNotOptimize(writes->data());
  }
}
BENCHMARK(BM_Phase_Writes)->Unit(benchmark::kMillisecond);

void BM_Phase_Encode(benchmark::State& state) {
  const auto device = *cfg::parse_device_description(generated()).device;
  cfg::Diagnostics diagnostics;
  const auto writes = *cfg::concise_writes_from_dcf(device, {}, diagnostics);
  for (auto _ : state) {
    auto stream = cfg::encode_concise_dcf(writes);
    benchmark::DoNotOptimize(stream.data());
  }
}
BENCHMARK(BM_Phase_Encode)->Unit(benchmark::kMicrosecond);

// Streaming decode of the generated stream in 64 KiB chunks, as dcf2concise --decode feeds it.
void BM_Decode_Streaming(benchmark::State& state) {
  const auto device = *cfg::parse_device_description(generated()).device;
  cfg::Diagnostics diagnostics;
  const auto stream =
      cfg::encode_concise_dcf(*cfg::concise_writes_from_dcf(device, {}, diagnostics));
  const std::size_t chunk = 64 * 1024;
  for (auto _ : state) {
    std::size_t entries = 0;
    cfg::ConciseDcfDecoder decoder(
        [&entries](std::uint16_t, std::uint8_t, std::span<const std::uint8_t>) { ++entries; });
    for (std::size_t pos = 0; pos < stream.size(); pos += chunk) {
      auto status =
          decoder.feed(std::span(stream).subspan(pos, std::min(chunk, stream.size() - pos)));
      benchmark::DoNotOptimize(status.ok());
    }
    auto status = decoder.finish();
    benchmark::DoNotOptimize(status.ok());
    benchmark::DoNotOptimize(entries);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * stream.size()));
}
BENCHMARK(BM_Decode_Streaming)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
