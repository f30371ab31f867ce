// The CiA 302-2 NMT master on a real bus, driven by a second thread: the master (node 1, built
// from an nmt::MasterConfig) boots the slaves named on the command line on `socketcan:can0` (or
// the bus URL given first: `socketcan:IFNAME`, `udp://GROUP:PORT`) in BusEventLoop on the main
// thread, while a console thread reads commands from stdin and hands them to the running master
// with EngineRef::post (the loop runs them on its own thread, between two engine calls):
//
//   read NODE INDEX SUB     SDO upload, e.g. `read 2 0x1018 1` (the answer comes as an event)
//   nmt NODE start|stop|preop|reset|resetcomm
//                           request NMT (1F82h) for NODE, or `all`
//   state                   start-up state and what the master knows of each slave
//   quit                    (or end of input, or Ctrl-C) stops the loop
//
//   socketcan_master [URL [SLAVE...]]     (default: socketcan:can0 2)
//
// Exit status: 0 after quit, 1 when the bus cannot be opened or fails, 2 on a usage error.
#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdint>
#include <iostream>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cfg/hex.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/master/master_config.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/master/nmt_master.hpp"

using namespace std::chrono_literals;

namespace {

std::atomic<nmt::BusEventLoop*> g_loop{nullptr};
extern "C" void on_signal(int /*signal*/) {
  if (auto* loop = g_loop.load()) loop->request_stop();  // async-signal-safe
}

// Both threads print: whole lines, one at a time.
std::mutex g_print_mutex;
void print(const std::string& line) {
  const std::lock_guard lock(g_print_mutex);
  std::cout << line << std::endl;
}

std::optional<std::uint64_t> number(const std::string& word) {
  try {
    std::size_t used = 0;
    const auto value = std::stoull(word, &used, 0);  // 0x.. or decimal
    if (used == word.size()) return value;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

// 1F82h values (CiA 302-2 Table 28).
std::optional<nmt::NmtRequest> request_value(const std::string& word) {
  if (word == "stop") return nmt::NmtRequest::Stop;
  if (word == "start") return nmt::NmtRequest::Start;
  if (word == "reset") return nmt::NmtRequest::ResetNode;
  if (word == "resetcomm") return nmt::NmtRequest::ResetCommunication;
  if (word == "preop") return nmt::NmtRequest::EnterPreOperational;
  return std::nullopt;
}

using Master = nmt::EngineRef<nmt::NmtMaster>;

// One console line; runs on the console thread and posts the work to the loop.
void command(const std::string& line, Master& master, nmt::BusEventLoop& loop) {
  std::istringstream in(line);
  std::string verb;
  in >> verb;
  if (verb.empty()) return;
  if (verb == "quit") {
    loop.post([&loop] { loop.request_stop(); });
  } else if (verb == "state") {
    master.post([](nmt::NmtMaster& m, nmt::TimePoint, nmt::NmtMaster::Output&) {
      std::string text = "start-up " + std::string(nmt::to_string(m.startup_state()));
      for (unsigned n = 1; n <= 127; ++n) {
        const auto node = cfg::NodeId::from(n).value();
        if (const auto known = m.known_state(node); known != nmt::KnownState::unknown()) {
          text += "; node " + std::to_string(n) + " " + cfg::hex(known.to_byte(), 2);
        }
      }
      print(text);
    });
  } else if (verb == "read") {
    std::string node_word, index_word, sub_word;
    in >> node_word >> index_word >> sub_word;
    const auto node = number(node_word);
    const auto index = number(index_word);
    const auto sub = number(sub_word);
    if (!node || !cfg::NodeId::from(*node) || !index || *index > 0xFFFF || !sub || *sub > 0xFF) {
      print("usage: read NODE INDEX SUB (node 1..127, e.g. read 2 0x1018 1)");
      return;
    }
    master.post([node = cfg::NodeId::from(*node).value(), index = std::uint16_t(*index),
                 sub = std::uint8_t(*sub)](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) {
      // Started: it ends in MasterEvent::SdoFinished; else the error says why (nothing sent).
      if (auto id = m.sdo_upload(node, index, sub, now, out); !id) {
        print("read refused: " + id.error().message);
      }
    });
  } else if (verb == "nmt") {
    std::string node_word, what;
    in >> node_word >> what;
    std::optional<nmt::NmtTarget> target;
    if (node_word == "all") {
      target = nmt::NmtTarget::all_nodes();
    } else if (const auto node = cfg::NodeId::from(number(node_word).value_or(0))) {
      target = nmt::NmtTarget(*node);
    }
    const auto value = request_value(what);
    if (!target || !value) {
      print("usage: nmt NODE|all start|stop|preop|reset|resetcomm");
      return;
    }
    master.post([target = *target, v = *value](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) {
      const auto abort = m.request_nmt(target, v, now, out);
      if (abort != nmt::SdoAbort::None) print("request NMT refused: " + nmt::to_string(abort));
    });
  } else {
    print("unknown command '" + verb + "' (read, nmt, state, quit)");
  }
}

// The console thread: reads lines until quit, end of input or `stop` (the loop ended).
void console(Master& master, nmt::BusEventLoop& loop, const std::atomic<bool>& stop) {
  std::string pending;
  char buffer[256];
  while (!stop.load()) {
    pollfd in{STDIN_FILENO, POLLIN, 0};
    if (::poll(&in, 1, 200) <= 0) continue;  // look at `stop` now and then
    const ssize_t n = ::read(STDIN_FILENO, buffer, sizeof buffer);
    if (n <= 0) {  // end of input
      loop.post([&loop] { loop.request_stop(); });
      return;
    }
    pending.append(buffer, static_cast<std::size_t>(n));
    for (auto end = pending.find('\n'); end != std::string::npos; end = pending.find('\n')) {
      const std::string line = pending.substr(0, end);
      pending.erase(0, end + 1);
      command(line, master, loop);
      if (line == "quit") return;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::string url = argc > 1 ? argv[1] : "socketcan:can0";
  nmt::MasterConfig config(cfg::NodeId::from(1).value());
  for (int i = 2; i < argc; ++i) {
    const auto node = number(argv[i]);
    if (!node || !cfg::NodeId::from(*node)) {
      std::cerr << "socketcan_master: '" << argv[i] << "' is no node-ID (1..127)\n";
      return 2;
    }
    config.add_slave(cfg::NodeId::from(*node).value());  // optional, boot and start it
  }
  if (argc <= 2) config.add_slave(cfg::NodeId::from(2).value());
  config.options.sdo.timeout = 500ms;
  auto built = config.build();
  if (!built) return std::cerr << "socketcan_master: " << built.error().message << "\n", 2;
  nmt::NmtMaster engine = std::move(built).value();

  auto bus = nmt::open_bus(url);
  if (!bus) return std::cerr << "socketcan_master: " << bus.error().message << "\n", 1;
  nmt::BusEventLoop loop(**bus);
  const nmt::TimePoint started = loop.now();  // events print their time since the start
  Master master(engine, [started](const nmt::MasterEvent& e, nmt::TimePoint now) {
    std::string line = std::to_string((now - started).count() / 1000) + " ms  " +
                       std::string(nmt::to_string(e.kind)) + ": " + nmt::describe(e);
    if (e.kind == nmt::MasterEvent::Kind::SdoFinished && e.sdo && e.sdo->upload &&
        e.sdo->abort == nmt::SdoAbort::None) {
      line += " =";
      for (const std::uint8_t b : e.sdo->data) line += " " + cfg::hex_digits(b, 2);
    }
    print(line);
  });
  loop.add(master);

  g_loop = &loop;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  master.apply([](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) { m.start(now, out); });
  print("master on " + url +
        "; commands: read NODE INDEX SUB, nmt NODE start|stop|..., state, "
        "quit");

  std::atomic<bool> stop{false};
  std::thread reader(console, std::ref(master), std::ref(loop), std::cref(stop));
  auto status = loop.run();
  stop = true;
  reader.join();
  g_loop = nullptr;
  if (status) {
    loop.clear_stop();
    status = loop.run_until_sent(500ms);  // the last commands leave before the program ends
  }
  if (!status) return std::cerr << "socketcan_master: " << status.error().message << "\n", 1;
  return 0;
}
