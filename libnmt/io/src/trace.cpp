// Trace writers (candump log, pcap) and the tracing decorators. Formats: can-utils' candump -l
// log (lib.c sprint_canframe / parse_canframe), and the tcpdump.org LINKTYPE_CAN_SOCKETCAN page.
#include "nmt/io/trace.hpp"

#include <array>
#include <cassert>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <utility>

#include "pcap_library.hpp"

namespace nmt {

namespace {

// Linux <linux/can.h> can_id flags, as LINKTYPE_CAN_SOCKETCAN carries them (CAN_ERR_FLAG is
// CanFrame::kErrorFlag).
constexpr std::uint32_t kCanEffFlag = 0x80000000u;
constexpr std::uint32_t kCanRtrFlag = 0x40000000u;

cfg::Status check_frame(const CanFrame& frame, TimePoint timestamp) {
  if (frame.dlc > 8) return cfg::Error{"frame " + to_candump(frame) + " has dlc > 8"};
  if (timestamp.time_since_epoch().count() < 0)
    return cfg::Error{"negative timestamp for " + to_candump(frame)};
  return {};
}

// Sticky first failure, shared by the writers.
class StatusKeeper {
 public:
  const cfg::Status& status() const { return status_; }
  cfg::Status fail(const std::filesystem::path& path, std::string message) {
    if (status_) status_ = cfg::Error{path.string() + ": " + std::move(message)};
    return status_;
  }

 private:
  cfg::Status status_;
};

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

class CandumpLogWriter final : public TraceWriter {
 public:
  CandumpLogWriter(std::filesystem::path path, std::unique_ptr<std::FILE, FileCloser> file,
                   std::string channel)
      : path_(std::move(path)), file_(std::move(file)), channel_(std::move(channel)) {}

  cfg::Status write(const CanFrame& frame, TimePoint timestamp) override {
    if (!keeper_.status()) return keeper_.status();
    if (auto st = check_frame(frame, timestamp); !st)
      return keeper_.fail(path_, st.error().message);
    // candump -l: "(%010lu.%06lu) %s %s\n" (seconds, microseconds, interface, frame).
    const auto us = timestamp.time_since_epoch().count();
    if (std::fprintf(file_.get(), "(%010" PRId64 ".%06" PRId64 ") %s %s\n",
                     static_cast<std::int64_t>(us / 1'000'000),
                     static_cast<std::int64_t>(us % 1'000'000), channel_.c_str(),
                     to_candump(frame).c_str()) < 0) {
      return keeper_.fail(path_, std::string("write failed: ") + std::strerror(errno));
    }
    return {};
  }
  cfg::Status flush() override {
    if (!keeper_.status()) return keeper_.status();
    if (std::fflush(file_.get()) != 0 || std::ferror(file_.get())) {
      return keeper_.fail(path_, std::string("write failed: ") + std::strerror(errno));
    }
    return {};
  }
  cfg::Status status() const override { return keeper_.status(); }
  const std::filesystem::path& path() const override { return path_; }

 private:
  std::filesystem::path path_;
  std::unique_ptr<std::FILE, FileCloser> file_;
  std::string channel_;
  StatusKeeper keeper_;
};

class PcapWriter final : public TraceWriter {
 public:
  PcapWriter(std::filesystem::path path, const detail::PcapLibrary& pcap, pcap_t* handle,
             pcap_dumper_t* dumper)
      : path_(std::move(path)), pcap_(pcap), handle_(handle), dumper_(dumper) {}
  ~PcapWriter() override {
    pcap_.dump_close(dumper_);
    pcap_.close(handle_);
  }
  PcapWriter(const PcapWriter&) = delete;
  PcapWriter& operator=(const PcapWriter&) = delete;

  cfg::Status write(const CanFrame& frame, TimePoint timestamp) override {
    if (!keeper_.status()) return keeper_.status();
    if (auto st = check_frame(frame, timestamp); !st)
      return keeper_.fail(path_, st.error().message);
    // LINKTYPE_CAN_SOCKETCAN: struct can_frame with the id word in network byte order. Error
    // frames carry CAN_ERR_FLAG and the error class, without CAN_EFF_FLAG (as the kernel sends
    // them); data bytes of remote frames are zero.
    std::uint32_t can_id = frame.id;
    if (frame.error) {
      can_id |= CanFrame::kErrorFlag;
    } else {
      if (frame.extended) can_id |= kCanEffFlag;
      if (frame.rtr) can_id |= kCanRtrFlag;
    }
    std::array<std::uint8_t, 16> record{};
    record[0] = static_cast<std::uint8_t>(can_id >> 24);
    record[1] = static_cast<std::uint8_t>(can_id >> 16);
    record[2] = static_cast<std::uint8_t>(can_id >> 8);
    record[3] = static_cast<std::uint8_t>(can_id);
    record[4] = frame.dlc;  // bytes 5..7: padding and reserved, zero
    if (!frame.rtr) std::copy_n(frame.data.begin(), frame.dlc, record.begin() + 8);

    pcap_pkthdr header{};
    header.ts.tv_sec = static_cast<time_t>(timestamp.time_since_epoch().count() / 1'000'000);
    header.ts.tv_usec = static_cast<suseconds_t>(timestamp.time_since_epoch().count() % 1'000'000);
    header.caplen = record.size();
    header.len = record.size();
    pcap_.dump(reinterpret_cast<u_char*>(dumper_), &header, record.data());
    if (std::ferror(pcap_.dump_file(dumper_))) {
      return keeper_.fail(path_, std::string("write failed: ") + std::strerror(errno));
    }
    return {};
  }
  cfg::Status flush() override {
    if (!keeper_.status()) return keeper_.status();
    if (pcap_.dump_flush(dumper_) != 0) {
      return keeper_.fail(path_, std::string("write failed: ") + std::strerror(errno));
    }
    return {};
  }
  cfg::Status status() const override { return keeper_.status(); }
  const std::filesystem::path& path() const override { return path_; }

 private:
  std::filesystem::path path_;
  const detail::PcapLibrary& pcap_;
  pcap_t* handle_;
  pcap_dumper_t* dumper_;
  StatusKeeper keeper_;
};

}  // namespace

cfg::Result<std::unique_ptr<TraceWriter>> open_candump_log(const std::filesystem::path& path,
                                                           const std::string& channel) {
  // The channel is one white-space separated field of the line (and an interface name).
  if (channel.empty() || channel.size() > 15 ||
      channel.find_first_of(" \t\r\n()#") != std::string::npos) {
    return cfg::Error{path.string() + ": channel '" + channel +
                      "' is not an interface name (1 to 15 characters, no white space)"};
  }
  std::unique_ptr<std::FILE, FileCloser> file(std::fopen(path.c_str(), "w"));
  if (!file) return cfg::Error{path.string() + ": cannot create: " + std::strerror(errno)};
  return std::unique_ptr<TraceWriter>(
      std::make_unique<CandumpLogWriter>(path, std::move(file), channel));
}

cfg::Result<std::unique_ptr<TraceWriter>> open_pcap(const std::filesystem::path& path) {
  const auto library = detail::pcap_library();
  if (!library) {
    return cfg::Error{path.string() + ": " + library.error().message, library.error().category};
  }
  const detail::PcapLibrary& pcap = **library;
  // Snapshot length: one struct can_frame (16 bytes) always fits.
  pcap_t* handle = pcap.open_dead(DLT_CAN_SOCKETCAN, 65535);
  if (handle == nullptr) return cfg::Error{path.string() + ": libpcap cannot open a dead handle"};
  pcap_dumper_t* dumper = pcap.dump_open(handle, path.c_str());
  if (dumper == nullptr) {
    std::string message = path.string() + ": cannot create: " + pcap.geterr(handle);
    pcap.close(handle);
    return cfg::Error{message};
  }
  return std::unique_ptr<TraceWriter>(std::make_unique<PcapWriter>(path, pcap, handle, dumper));
}

cfg::Result<std::unique_ptr<TraceWriter>> open_trace(const std::filesystem::path& path) {
  const auto extension = path.extension();
  if (extension == ".log") return open_candump_log(path);
  if (extension == ".pcap") return open_pcap(path);
  return cfg::Error{path.string() +
                    ": unknown trace format; use .log (candump log) or .pcap (pcap, SocketCAN)"};
}

TracingBus::TracingBus(std::unique_ptr<Bus> inner, std::unique_ptr<TraceWriter> trace,
                       std::function<TimePoint()> clock)
    : inner_(std::move(inner)), trace_(std::move(trace)), clock_(std::move(clock)) {
  assert(inner_ != nullptr && trace_ != nullptr && clock_);
}

cfg::Status TracingBus::send(const CanFrame& frame) {
  auto status = inner_->send(frame);
  if (status) (void)trace_->write(frame, clock_());
  return status;
}

SendResult TracingBus::try_send(const CanFrame& frame) {
  auto result = inner_->try_send(frame);
  if (result.status == SendResult::Status::Sent) (void)trace_->write(frame, clock_());
  return result;
}

cfg::Result<std::optional<ReceivedFrame>> TracingBus::receive(Duration timeout) {
  auto received = inner_->receive(timeout);
  if (received && received->has_value()) (void)trace_->write((*received)->frame, clock_());
  return received;
}

std::string TracingBus::url() const {
  return inner_->url();
}

std::function<void(const CanFrame&, TimePoint)> trace_observer(TraceWriter& writer) {
  return [&writer](const CanFrame& frame, TimePoint at) { (void)writer.write(frame, at); };
}

}  // namespace nmt
