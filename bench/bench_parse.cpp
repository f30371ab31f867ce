// EDS/DCF parse throughput (MB/s and sub-objects/s) and peak heap use relative to the file size.
//
// Inputs: two DCFs generated here, 200 RECORDs of 255 sub-objects each (51,000 sub-objects):
// "Generated" has every key CANopenEditor writes for a DCF entry (about 11 MB, 217 bytes per
// entry), "Terse" only the keys CiA 306 requires plus a DefaultValue (about 6 MB, 124 bytes per
// entry); and the largest corpus file, oresat/c3.dcf (skipped when the corpus is absent). Baseline
// in the same run: a memchr line count over the same bytes, i.e. the cost of merely touching every
// line; report the parse figure as a ratio to it. Memory: the global operator new is counted;
// "peak_heap_per_file_byte" is the largest heap in use during one parse (the model plus everything
// transient, not counting the text, which the caller owns) divided by the file size;
// "model_heap_per_file_byte" is what the result still holds after the parse (model and
// diagnostics).
//
// Run (Release): cmake -B build-rel -DCMAKE_BUILD_TYPE=Release && cmake --build build-rel
//   --target bench_parse && build-rel/bench/bench_parse
#include <benchmark/benchmark.h>
#include <malloc.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <new>
#include <optional>
#include <sstream>
#include <string>

#include "cfg/device_file.hpp"

// ---- counting allocator (whole program; single-threaded benchmark)
namespace {
std::atomic<std::size_t> g_in_use{0};
std::atomic<std::size_t> g_peak{0};

void* counted_alloc(std::size_t n) {
  void* p = std::malloc(n == 0 ? 1 : n);
  if (p == nullptr) throw std::bad_alloc();
  const std::size_t now = g_in_use += malloc_usable_size(p);
  std::size_t peak = g_peak.load();
  while (now > peak && !g_peak.compare_exchange_weak(peak, now)) {
  }
  return p;
}
void counted_free(void* p) noexcept {
  if (p == nullptr) return;
  g_in_use -= malloc_usable_size(p);
  std::free(p);
}
}  // namespace

void* operator new(std::size_t n) {
  return counted_alloc(n);
}
void* operator new[](std::size_t n) {
  return counted_alloc(n);
}
void operator delete(void* p) noexcept {
  counted_free(p);
}
void operator delete[](void* p) noexcept {
  counted_free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  counted_free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  counted_free(p);
}

namespace {

constexpr int kObjects = 200;
constexpr int kSubsPerObject = 255;  // sub-indices 0..254

// A DCF as CANopenEditor writes one, with a mix of types and value forms.
const std::string& generated_dcf() {
  static const std::string text = [] {
    std::string s;
    s.reserve(13'000'000);
    s += "[FileInfo]\r\nFileName=generated.dcf\r\nFileVersion=1\r\nFileRevision=0\r\n"
         "EDSVersion=4.0\r\nDescription=bench_parse generated DCF\r\nCreatedBy=bench\r\n\r\n"
         "[DeviceInfo]\r\nVendorName=Bench\r\nVendorNumber=0x00000001\r\nProductName=Big\r\n"
         "ProductNumber=0x2\r\nRevisionNumber=0x1\r\nBaudRate_500=1\r\nGranularity=8\r\n\r\n"
         "[DummyUsage]\r\nDummy0005=1\r\n\r\n"
         "[MandatoryObjects]\r\nSupportedObjects=0\r\n\r\n"
         "[OptionalObjects]\r\nSupportedObjects=0\r\n\r\n"
         "[ManufacturerObjects]\r\nSupportedObjects=" +
         std::to_string(kObjects) + "\r\n";
    char buf[512];
    for (int i = 0; i < kObjects; ++i) {
      std::snprintf(buf, sizeof buf, "%d=0x%04X\r\n", i + 1, 0x2000 + i);
      s += buf;
    }
    for (int i = 0; i < kObjects; ++i) {
      const int index = 0x2000 + i;
      std::snprintf(buf, sizeof buf,
                    "\r\n[%04X]\r\nParameterName=Generated record %d\r\nDenotation=\r\n"
                    "ObjectType=0x9\r\n;StorageLocation=RAM\r\nSubNumber=0x%X\r\n",
                    index, i, kSubsPerObject);
      s += buf;
      for (int sub = 0; sub < kSubsPerObject; ++sub) {
        if (sub == 0) {
          std::snprintf(buf, sizeof buf,
                        "\r\n[%04Xsub0]\r\nParameterName=Highest sub-index supported\r\n"
                        "Denotation=\r\nObjectType=0x7\r\n;StorageLocation=RAM\r\n"
                        "DataType=0x0005\r\nAccessType=ro\r\nDefaultValue=0x%02X\r\n"
                        "ParameterValue=\r\nPDOMapping=0\r\n",
                        index, kSubsPerObject - 1);
        } else if (sub % 3 == 0) {
          std::snprintf(buf, sizeof buf,
                        "\r\n[%04Xsub%X]\r\nParameterName=Setpoint %d of axis %d\r\n"
                        "Denotation=Axis %d setpoint\r\nObjectType=0x7\r\n"
                        ";StorageLocation=RAM\r\nDataType=0x0003\r\nAccessType=rww\r\n"
                        "DefaultValue=-%d\r\nParameterValue=%d\r\nLowLimit=-1000\r\n"
                        "HighLimit=1000\r\nPDOMapping=1\r\n",
                        index, sub, sub, i, sub, sub % 1000, (sub * 7) % 1000);
        } else if (sub % 3 == 1) {
          std::snprintf(buf, sizeof buf,
                        "\r\n[%04Xsub%X]\r\nParameterName=COB-ID of channel %d\r\n"
                        "Denotation=\r\nObjectType=0x7\r\n;StorageLocation=PERSIST_COMM\r\n"
                        "DataType=0x0007\r\nAccessType=rw\r\nDefaultValue=$NODEID+0x%X\r\n"
                        "ParameterValue=0x%08X\r\nPDOMapping=0\r\n",
                        index, sub, sub, 0x180 + sub, 0x80000000U + static_cast<unsigned>(sub));
        } else {
          std::snprintf(buf, sizeof buf,
                        "\r\n[%04Xsub%X]\r\nParameterName=Label %d\r\nDenotation=\r\n"
                        "ObjectType=0x7\r\n;StorageLocation=ROM\r\nDataType=0x0009\r\n"
                        "AccessType=ro\r\nDefaultValue=Label text %d; with a semicolon\r\n"
                        "ParameterValue=\r\nPDOMapping=0\r\n",
                        index, sub, sub, sub);
        }
        s += buf;
      }
    }
    return s;
  }();
  return text;
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

// Only what CiA 306 asks of an entry, plus a DefaultValue: the smallest realistic entry.
const std::string& terse_dcf() {
  static const std::string text = [] {
    std::string s;
    s.reserve(7'000'000);
    s += "[FileInfo]\r\nFileName=terse.dcf\r\n\r\n[DeviceInfo]\r\nVendorName=Bench\r\n\r\n"
         "[ManufacturerObjects]\r\nSupportedObjects=" +
         std::to_string(kObjects) + "\r\n";
    char buf[256];
    for (int i = 0; i < kObjects; ++i) {
      std::snprintf(buf, sizeof buf, "%d=0x%04X\r\n", i + 1, 0x2000 + i);
      s += buf;
    }
    for (int i = 0; i < kObjects; ++i) {
      std::snprintf(buf, sizeof buf,
                    "\r\n[%04X]\r\nParameterName=Record %d\r\nObjectType=0x9\r\n"
                    "SubNumber=0x%X\r\n",
                    0x2000 + i, i, kSubsPerObject);
      s += buf;
      for (int sub = 0; sub < kSubsPerObject; ++sub) {
        std::snprintf(buf, sizeof buf,
                      "\r\n[%04Xsub%X]\r\nParameterName=Entry %d\r\nObjectType=0x7\r\n"
                      "DataType=0x0007\r\nAccessType=rw\r\nDefaultValue=0x%08X\r\n"
                      "PDOMapping=0\r\n",
                      0x2000 + i, sub, sub, static_cast<unsigned>(sub));
        s += buf;
      }
    }
    return s;
  }();
  return text;
}

const std::string* corpus_dcf() {
  static const std::string text = [] {
    const auto path = std::filesystem::path(CANOPEN_CORPUS_DIR) / "oresat" / "c3.dcf";
    return std::filesystem::exists(path) ? read_file(path) : std::string();
  }();
  return text.empty() ? nullptr : &text;
}

std::size_t count_subs(const cfg::DeviceDescription& d) {
  std::size_t n = 0;
  for (const auto& [index, obj] : d.objects) n += obj.subs.size();
  return n;
}

void parse_bench(benchmark::State& state, const std::string& text, cfg::ReadMode mode) {
  std::size_t subs = 0;
  std::size_t peak = 0;
  std::size_t kept = 0;
  std::optional<cfg::ReadResult> r;
  for (auto _ : state) {
    const std::size_t before = g_in_use.load();
    g_peak = before;
    r.emplace(cfg::parse_device_description(text, {mode, "bench.dcf"}));
    benchmark::DoNotOptimize(*r);
    // Parse only: reading the result and freeing the model are not timed.
    state.PauseTiming();
    peak = std::max(peak, g_peak.load() - before);
    kept = g_in_use.load() - before;
    if (!r->device) state.SkipWithError("the text did not parse");
    subs = r->device ? count_subs(*r->device) : 0;
    r.reset();
    state.ResumeTiming();
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * text.size()));
  state.counters["subobjects"] = static_cast<double>(subs);
  state.counters["subobjects/s"] = benchmark::Counter(
      static_cast<double>(subs * state.iterations()), benchmark::Counter::kIsRate);
  state.counters["file_bytes"] = static_cast<double>(text.size());
  state.counters["peak_heap_bytes"] = static_cast<double>(peak);
  state.counters["peak_heap_per_file_byte"] =
      static_cast<double>(peak) / static_cast<double>(text.size());
  state.counters["model_heap_per_file_byte"] =
      static_cast<double>(kept) / static_cast<double>(text.size());
  state.counters["sizeof_SubObject"] = sizeof(cfg::SubObject);
}

// Baseline: find every line end with memchr and touch the first byte of each line.
void memchr_bench(benchmark::State& state, const std::string& text) {
  for (auto _ : state) {
    std::size_t lines = 0;
    unsigned sum = 0;
    const char* p = text.data();
    const char* end = p + text.size();
    while (p < end) {
      const auto* nl = static_cast<const char*>(std::memchr(p, '\n', end - p));
      sum += static_cast<unsigned char>(*p);
      ++lines;
      if (nl == nullptr) break;
      p = nl + 1;
    }
    benchmark::DoNotOptimize(lines);
    benchmark::DoNotOptimize(sum);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * text.size()));
}

void BM_ParseGeneratedDcf(benchmark::State& state) {
  parse_bench(state, generated_dcf(), cfg::ReadMode::Tolerant);
}
void BM_ParseGeneratedDcfStrict(benchmark::State& state) {
  parse_bench(state, generated_dcf(), cfg::ReadMode::Strict);
}
void BM_BaselineMemchrLinesGeneratedDcf(benchmark::State& state) {
  memchr_bench(state, generated_dcf());
}
void BM_ParseTerseDcf(benchmark::State& state) {
  parse_bench(state, terse_dcf(), cfg::ReadMode::Tolerant);
}
void BM_BaselineMemchrLinesTerseDcf(benchmark::State& state) {
  memchr_bench(state, terse_dcf());
}
void BM_ParseCorpusC3Dcf(benchmark::State& state) {
  if (const std::string* text = corpus_dcf()) {
    parse_bench(state, *text, cfg::ReadMode::Tolerant);
  } else {
    state.SkipWithError("corpus oresat/c3.dcf absent (../shared/corpus)");
  }
}
void BM_BaselineMemchrLinesCorpusC3Dcf(benchmark::State& state) {
  if (const std::string* text = corpus_dcf()) {
    memchr_bench(state, *text);
  } else {
    state.SkipWithError("corpus oresat/c3.dcf absent (../shared/corpus)");
  }
}
void BM_WriteGeneratedDcf(benchmark::State& state) {
  const cfg::ReadResult r = cfg::parse_device_description(generated_dcf());
  if (!r.device) {
    state.SkipWithError("the text did not parse");
    return;
  }
  std::size_t bytes = 0;
  for (auto _ : state) {
    std::string out = cfg::write_device_description(*r.device);
    bytes = out.size();
    benchmark::DoNotOptimize(out);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
}

BENCHMARK(BM_ParseGeneratedDcf)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ParseGeneratedDcfStrict)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BaselineMemchrLinesGeneratedDcf)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ParseTerseDcf)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BaselineMemchrLinesTerseDcf)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ParseCorpusC3Dcf)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BaselineMemchrLinesCorpusC3Dcf)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_WriteGeneratedDcf)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
