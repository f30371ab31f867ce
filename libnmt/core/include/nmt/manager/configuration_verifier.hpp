// Reading a node's configuration back: for every value a configuration writes (a concise DCF's
// entries, a DCF's configured values), an SDO upload (CiA 301 §7.2.4.3) of the entry and the
// bytes the device has against the bytes the configuration writes. It writes nothing. The engine
// under `cfgmgr verify`; an nmt::Engine (nmt/engine.hpp) on an SdoClientMux, one client per
// node, so nodes are read at once and each node's entries one after the other.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <utility>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_abort.hpp"
#include "nmt/sdo/sdo_client.hpp"

namespace nmt {

/// The outcome of reading back one entry.
struct VerifyResult {
  cfg::NodeId node_id;
  cfg::ObjectAddress address;
  std::vector<std::uint8_t> expected{};  ///< what the configuration writes
  std::vector<std::uint8_t> actual{};    ///< what the device answered (empty when it failed)
  SdoAbort abort = SdoAbort::None;       ///< None: read; else why the upload failed (last try)
  unsigned attempts = 1;                 ///< uploads made (more than 1 after timeouts); 0: none
  /// The node never answered: its first upload went unanswered, so it was neither repeated nor
  /// were the node's other entries asked (each reported with abort Timeout and 0 attempts).
  bool unreachable = false;

  bool read() const { return abort == SdoAbort::None; }
  /// Read, and byte for byte what the configuration writes.
  bool same() const { return read() && actual == expected; }
};

struct VerifyOptions {
  SdoTransferOptions sdo{};  ///< timeout of each response, largest value accepted
  /// How often an upload that timed out (0504 0000, a lost frame) is made again, to a node
  /// that answered before or whose heartbeat was seen. Other aborts are the device's answer and
  /// final. A node whose first upload goes unanswered and that was never heard is taken as
  /// absent: no repetition and none of its other entries, so an absent node costs one timeout,
  /// not one per entry and try.
  unsigned retries = 2;
};

class ConfigurationVerifier {
 public:
  using Event = VerifyResult;
  using Output = Outbox<VerifyResult>;

  explicit ConfigurationVerifier(VerifyOptions options = {}) : options_(options) {}

  /// Reads back `writes` from `node` (default SDO channel, 600h/580h + node-ID): one upload per
  /// entry, in the order each entry first appears; an entry written more than once is compared
  /// with its last write (the value a download leaves, as cfg::order_for_download applies it).
  /// The first request goes into `out` at once; each entry ends with one VerifyResult.
  void verify(cfg::NodeId node, std::span<const cfg::ObjectWrite> writes, TimePoint now,
              Output& out);

  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const { return mux_.next_deadline(); }

  /// Entries not yet reported.
  std::size_t pending() const { return running_.size(); }

 private:
  struct Running {
    VerifyResult result;
  };
  // Turns the mux's results into VerifyResults, uploading again after a timeout.
  void take(Outbox<SdoResult>& sdo, TimePoint now, Output& out);
  void upload(VerifyResult result, TimePoint now, Outbox<SdoResult>& sdo, Output& out);

  VerifyOptions options_;
  SdoClientMux mux_;
  Outbox<SdoResult> sdo_;  ///< the mux's output in a call, cleared before each use (no allocation)
  // By node-ID << 32 | transfer id (ids count per client).
  std::map<std::uint64_t, Running> running_;
  // Nodes that answered at least once or were heard (heartbeat), and those taken as absent
  // (see VerifyOptions::retries).
  std::set<std::uint8_t> answered_;
  std::set<std::uint8_t> unreachable_;
};
static_assert(Engine<ConfigurationVerifier>);

}  // namespace nmt
