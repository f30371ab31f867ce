// Software update in the boot (DSP 302 §9) as `cfgmgr push` runs it on sim: at
// 500 kbit/s: a 256 KiB image (262 144 bytes, our version trailer included) to 1 node and to 10
// nodes (tests/data/program/nodes/drive_node3.dcf at node-IDs 1..N, 1F52h differing), and the
// same networks booted without the update (--program-version = the devices' 1F52h).
//   cmake --build build --target bench_program_update && build/bench/bench_program_update
// The bound is the air time (nmt::frame_bits, stuff bits included) of the frames the update
// needs with the fastest standard transfer, per node: 1F51h sub 1 = 0 (stop), the 1F50h sub 1
// block download (CiA 301 §7.2.4.3.9-13: initiate, 37 450 segments of 7 bytes in blocks of 127,
// one acknowledgement per block, end with CRC) and 1F51h sub 1 = 1 (start), each with its
// response. The clear (1F51h = 3) and the 1F52h reads are not in it: they are the overhead.
// Measured: for 1 node the update's own seconds (--json nodes[].program.seconds: stop to start
// confirmed); for N nodes the push's bus time with the update minus without it, against N x the
// bound (the bus carries one frame at a time).
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/program_image.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/protocol/frame_bits.hpp"
#include "process_runner.hpp"

namespace {

namespace fs = std::filesystem;
constexpr std::uint32_t kBitrate = 500'000;
constexpr std::size_t kImageSize = 256 * 1024;
const cfg::ProgramVersion kNew{15671, 29'700'000};  // 2026-11-27 08:15, the image's
const char* const kOld = "15188,27000000";          // drive_node3.dcf's 1F52h

std::string slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

double number_after(const std::string& text, const std::string& key, std::size_t from = 0) {
  const auto at = text.find("\"" + key + "\": ", from);
  return at == std::string::npos ? -1 : std::strtod(text.c_str() + at + key.size() + 4, nullptr);
}

// The network: N copies of the test drive with a program, in `dir`.
void write_network(const fs::path& dir, int nodes) {
  const std::string dcf = slurp(fs::path(CANOPEN_TEST_DATA_DIR) / "program/nodes/drive_node3.dcf");
  std::ofstream cpj(dir / "net.cpj");
  cpj << "[Topology]\nNodes=" << nodes << "\n";
  for (int n = 1; n <= nodes; ++n) {
    std::string text = dcf;
    text.replace(text.find("NodeID=3"), 8, "NodeID=" + std::to_string(n));
    std::ofstream(dir / ("node" + std::to_string(n) + ".dcf")) << text;
    cpj << "Node" << n << "Present=1\nNode" << n << "DCFName=node" << n << ".dcf\nNode" << n
        << "ProgramFile=image.bin\nNode" << n << "ProgramVersion=15671,29700000\n";
  }
}

std::vector<std::uint8_t> make_image() {
  std::mt19937 random(24);
  std::vector<std::uint8_t> payload(kImageSize - cfg::kProgramTrailerSize);
  for (auto& b : payload) b = static_cast<std::uint8_t>(random());
  return cfg::with_program_trailer(payload, kNew);
}

std::uint64_t bits(std::uint32_t id, const std::vector<std::uint8_t>& data) {
  return nmt::frame_bits(nmt::CanFrame::make(id, data)).total();
}

// Air time of stop, block download of `image`, start for node `node` (see the top).
double bound_s(const std::vector<std::uint8_t>& image, std::uint8_t node) {
  const std::uint32_t rx = 0x600U + node;
  const std::uint32_t tx = 0x580U + node;
  std::uint64_t total = 0;
  const auto expedited = [&](std::uint8_t value) {
    total += bits(rx, {0x2F, 0x51, 0x1F, 0x01, value, 0, 0, 0});
    total += bits(tx, {0x60, 0x51, 0x1F, 0x01, 0, 0, 0, 0});
  };
  expedited(0);
  std::vector<std::uint8_t> init{0xC6, 0x50, 0x1F, 0x01};
  cfg::append_le(init, image.size(), 4);
  total += bits(rx, init);
  total += bits(tx, {0xA4, 0x50, 0x1F, 0x01, 127, 0, 0, 0});
  const std::size_t segments = (image.size() + 6) / 7;
  for (std::size_t s = 0; s < segments; ++s) {
    const std::uint8_t seqno = static_cast<std::uint8_t>(s % 127 + 1);
    std::vector<std::uint8_t> frame{
        static_cast<std::uint8_t>(seqno | (s + 1 == segments ? 0x80 : 0))};
    for (std::size_t i = 0; i < 7; ++i) {
      const std::size_t at = s * 7 + i;
      frame.push_back(at < image.size() ? image[at] : 0);
    }
    total += bits(rx, frame);
    if (seqno == 127 || s + 1 == segments) total += bits(tx, {0xA2, seqno, 127, 0, 0, 0, 0, 0});
  }
  total += bits(rx, {0xC1, 0x34, 0x12, 0, 0, 0, 0, 0});
  total += bits(tx, {0xA1, 0, 0, 0, 0, 0, 0, 0});
  expedited(1);
  return static_cast<double>(total) / kBitrate;
}

struct Push {
  double transfer_s = -1;  ///< node 1: the 1F50h initiate request to the end response (trace)
  double bus_s = -1;
  double update_s = -1;  ///< node 1's program.seconds
  double wall_s = 0;
  int exit_code = -1;
};

Push push(const fs::path& dir, int nodes, bool update) {
  std::vector<std::string> args = {CANOPEN_CFGMGR, "push",   (dir / "net.cpj").string(), "--bus",
                                   "sim:",         "--json", (dir / "r.json").string()};
  if (!update) {
    for (int n = 1; n <= nodes; ++n) {
      args.push_back("--program-version");
      args.push_back(std::to_string(n) + "=" + kOld);
    }
  }
  args.push_back("--candump");
  args.push_back((dir / "t.log").string());
  const bench::ProcessSample sample = bench::run_process(args);
  Push p;
  p.exit_code = sample.exit_code;
  p.wall_s = sample.wall_ms / 1e3;
  const std::string report = slurp(dir / "r.json");
  p.bus_s = number_after(report, "elapsed_s");
  const auto program = report.find("\"program\": {");
  if (program != std::string::npos) p.update_s = number_after(report, "seconds", program);
  // candump lines "(SECONDS) can0 ID#DATA": node 1's block download initiate (601#C6501F01)
  // to its end response (581#A1).
  const std::string log = slurp(dir / "t.log");
  const auto time_before = [&log](std::size_t at) {
    const auto open = log.rfind('(', at);
    return std::strtod(log.c_str() + open + 1, nullptr);
  };
  const auto begin = log.find("601#C6501F01");
  const auto end = log.find("581#A1", begin == std::string::npos ? 0 : begin);
  if (begin != std::string::npos && end != std::string::npos) {
    p.transfer_s = time_before(end) - time_before(begin);
  }
  return p;
}

}  // namespace

int main() {
  const auto image = make_image();
  std::printf("image %zu bytes at %u bit/s; bound per node (stop, block download, start): %.3f s\n",
              image.size(), kBitrate, bound_s(image, 1));
  std::printf(
      "| nodes | boot with update | boot without | difference | bound (N x) | ratio | node 1's "
      "update step | node 1's 1F50h block download | wall with update |\n");
  std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  for (const int nodes : {1, 10}) {
    const fs::path dir =
        fs::temp_directory_path() / ("bench_program_update_" + std::to_string(nodes));
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::ofstream(dir / "image.bin", std::ios::binary)
        .write(reinterpret_cast<const char*>(image.data()),
               static_cast<std::streamsize>(image.size()));
    write_network(dir, nodes);
    const Push with = push(dir, nodes, true);
    const Push without = push(dir, nodes, false);
    if (with.exit_code != 0 || without.exit_code != 0) {
      std::fprintf(stderr, "bench_program_update: push exited %d / %d (%s)\n", with.exit_code,
                   without.exit_code, dir.c_str());
      return 1;
    }
    double bound = 0;
    for (int n = 1; n <= nodes; ++n) bound += bound_s(image, static_cast<std::uint8_t>(n));
    const double difference = with.bus_s - without.bus_s;
    std::printf(
        "| %d | %.3f s | %.3f s | %.3f s | %.3f s | **%.3f** | %.3f s (%.3fx) | %.3f s | %.2f s "
        "|\n",
        nodes, with.bus_s, without.bus_s, difference, bound, difference / bound, with.update_s,
        with.update_s / bound_s(image, 1), with.transfer_s, with.wall_s);
    fs::remove_all(dir);
  }
  return 0;
}
