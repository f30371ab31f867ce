// The SDO requesting device (SRD) of DSP 302 §7: a CANopen device that asks the SDO manager for
// SDO connections instead of taking another node's default SDO. An nmt::Engine (nmt/engine.hpp)
// made of a SlaveNode (its dictionary with 1F10h, 1F11h and the client entries 1280h-12FFh, its
// heartbeat, its default SDO server on which the manager scans and writes) and one SdoClient per
// connection the manager set up.
//   auto srd = SdoRequestingDevice::create(description, node_id).value();
//   srd->start(now, out);                   // boots like any slave (boot-up from on_timer)
//   srd->register_at_manager(now, out);        // 1F10h = index<<16 | 1, then 6E0h#  (§7.2.1)
//   ... SrdEvent::Kind::Registered ...
//   srd->request_connection(5, 0x1281, now, out);  // 1F00h at the manager (§7.2.2)
//   ... SrdEvent::Kind::Connected (client entry 1281h now holds the manager's COB-IDs) ...
//   srd->upload(0x1281, 0x1008, 0, now, out);  // an SdoResult in SrdEvent::transfer
//   srd->release(5, 0x1281, now, out);         // 1F01h; the manager invalidates 1281h
//
// Behaviour where DSP 302 leaves room:
// - Registration: the SRD writes 1F10h into its own dictionary, then sends the Dynamic SDO
//   Request. It is registered when the manager writes 1F10h with Rq indication 0 and Cnxn state
//   1 (the channel to the manager is then the client entry that word names, read from the
//   dictionary as the manager wrote it) or 2 (all default SDOs owned). Cnxn state 0 with an
//   error code or a non-zero index is a refusal. A write of 00000000h is the manager's "reset"
//   of 1F10h after its scan (§7.2.1) and not yet the confirmation; so is any write while the
//   Rq indication bit stays 1.
// - §7.2.4 1: when no confirmation comes within SrdOptions::registration_timeout, the SRD reports
//   RegistrationFailed with "no SDO manager answered" and stays unregistered.
// - A connection request is an SDO download of 1F00h over the channel to the manager. An abort
//   (060A 0023) or a missing 1F10h confirmation within SrdOptions::connection_timeout ends it
//   with ConnectionFailed. One request at a time: the confirmation names only the client index.
// - Owning all default SDOs (Cnxn state 2), connections need no request: transfers address a
//   slave's default SDO with connect_default().
// - A connection ends when the manager sets bit 31 of sub 1 or sub 2 of its client entry
//   (release, error control loss of S): ConnectionReleased. The entry of the channel to the
//   manager invalidated ends the registration (Deregistered). A transfer running on a released
//   channel ends with abort 0800 0000 without a frame (the COB-IDs are gone).
// - 1F11h written by the manager is reported as SlaveFailed; the release follows as the manager
//   clears the client entry.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/result.hpp"
#include "cfg/sdo_manager_objects.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_client.hpp"
#include "nmt/slave/slave_node.hpp"

namespace nmt {

/// What the SRD reports.
struct SrdEvent {
  enum class Kind : std::uint8_t {
    Registered,          ///< the manager confirmed the registration (state: the word it wrote)
    RegistrationFailed,  ///< refused (state.error()) or no manager answered (text says which)
    Connected,           ///< a requested connection is ready on client_index
    ConnectionFailed,    ///< refused by abort, by 1F10h error code, or timed out
    ReleaseFailed,       ///< the manager refused a 1F01h write (abort)
    ConnectionReleased,  ///< the manager invalidated client_index (release or slave failure)
    Deregistered,        ///< the channel to the manager is gone (1F01h slave 0, or the manager)
    SlaveFailed,         ///< 1F11h written by the manager (slave_node_id, reason in text)
    Transfer,            ///< an upload/download started through the SRD ended (transfer)
    Device,              ///< an event of the SRD's own node (boot-up, NMT, ...) in text
  };
  Kind kind = Kind::Device;
  TimePoint at{};
  std::uint16_t client_index = 0;              ///< 1280h-12FFh the event is about; 0 when none
  std::optional<cfg::NodeId> slave_node_id{};  ///< the slave (server) concerned; nullopt: none
  /// The 1F10h word the manager wrote (Registered, RegistrationFailed, Connected,
  /// ConnectionFailed by error code).
  cfg::sdo_manager::DynamicSdoState state{};
  /// An abort that ended a request (ConnectionFailed, RegistrationFailed); None otherwise.
  SdoAbort abort = SdoAbort::None;
  std::optional<SdoResult> transfer{};  ///< Transfer: the result; its id is the SRD's TransferId
  std::string text{};                   ///< one line for people
};

struct SrdOptions {
  /// The free client entry (1280h-12FFh) the manager shall use for the channel to itself.
  std::uint16_t registration_client_index = 0x1280;
  /// Ask the manager to watch the slaves the SRD connects to (1F10h xxxx0009h).
  bool request_error_control = false;
  /// Ask for all default SDOs instead of a channel to the manager (1F10h 00000003h).
  bool all_default_sdos = false;
  /// Longest wait for the manager's 1F10h confirmation of the registration.
  Duration registration_timeout = std::chrono::seconds(5);
  /// Longest wait for the 1F10h confirmation of a connection after 1F00h was accepted.
  Duration connection_timeout = std::chrono::seconds(5);
  /// Transfers of 1F00h/1F01h to the manager.
  SdoTransferOptions manager_transfer{};
  /// Options of the SRD's own node (its SDO server serves the manager's writes).
  SlaveNodeOptions node{};
};

/// Where the SRD stands with the manager.
enum class SrdRegistration : std::uint8_t {
  Unregistered,    ///< not registered (never, refused, timed out, or de-registered)
  Requested,       ///< Dynamic SDO Request sent, waiting for the manager
  Registered,      ///< channel to the manager established (Cnxn state 1)
  AllDefaultSdos,  ///< owns all default SDOs (Cnxn state 2)
};

/// One SRD. Not copyable or movable (its dictionary observers refer to it): create() hands out
/// a unique_ptr.
class SdoRequestingDevice {
  struct Key {
    explicit Key() = default;
  };

 public:
  using TransferId = std::uint32_t;
  using Event = SrdEvent;
  using Output = Outbox<SrdEvent>;

  /// Builds the SRD's node from its device description. Fails with a message when a value does
  /// not parse, when the description lacks 1F10h, or when options.registration_client_index is
  /// not a 1280h-12FFh entry of it (unless all_default_sdos).
  static cfg::Result<std::unique_ptr<SdoRequestingDevice>> create(
      const cfg::DeviceDescription& description, cfg::NodeId node_id, SrdOptions options = {});

  SdoRequestingDevice(const SdoRequestingDevice&) = delete;
  SdoRequestingDevice& operator=(const SdoRequestingDevice&) = delete;
  ~SdoRequestingDevice();

  // --- engine --------------------------------------------------------------------------------
  /// Powers the node on (SlaveNode::start): every connection and the registration are gone.
  void start(TimePoint now, Output& out);
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;

  // --- the SRD's requests (DSP 302 §7.2.1, §7.2.2) -------------------------------------------
  /// Sets 1F10h to the request of the options and sends the Dynamic SDO Request (6E0h, no data).
  /// An error (nothing sent) when the node is not booted (powered and out of initialisation) or
  /// a registration is already requested or done.
  cfg::Status register_at_manager(TimePoint now, Output& out);
  /// Asks the manager for a connection to `slave` on the SRD's client entry `client_index`
  /// (1F00h = client_index<<16 | node-ID<<8 | slave). An error (nothing sent) when not Registered,
  /// when another request is pending, or when `client_index` is no client entry of the
  /// dictionary. The outcome is Connected or ConnectionFailed.
  cfg::Status request_connection(cfg::NodeId slave, std::uint16_t client_index, TimePoint now,
                                 Output& out);
  /// Asks the manager to release the connection on `client_index` to `slave` (1F01h; 0 = every
  /// connection to `slave`). An error when not Registered or when another request is pending.
  /// The release is seen as ConnectionReleased when the manager invalidates the entry.
  cfg::Status release(cfg::NodeId slave, std::uint16_t client_index, TimePoint now, Output& out);
  /// Releases everything and de-registers (1F01h with slave node-ID 0). An error when not
  /// Registered or another request is pending. On success the SRD reports Deregistered.
  cfg::Status deregister(TimePoint now, Output& out);

  // --- transfers -----------------------------------------------------------------------------
  /// Starts an upload over the established connection on `client_index` (1280h-12FFh). An
  /// error (nothing sent) when there is no such connection. The result comes as a Transfer event
  /// with this TransferId.
  cfg::Result<TransferId> upload(std::uint16_t client_index, std::uint16_t index, std::uint8_t sub,
                                 TimePoint now, Output& out, SdoTransferOptions options = {});
  /// The same for a download of `data`.
  cfg::Result<TransferId> download(std::uint16_t client_index, std::uint16_t index,
                                   std::uint8_t sub, std::vector<std::uint8_t> data, TimePoint now,
                                   Output& out, SdoTransferOptions options = {});
  /// Upload / download over `slave`'s default SDO (600h/580h + node-ID), while registration()
  /// is AllDefaultSdos (DSP 302 §7.2.2: the SRD owns them); an error otherwise.
  cfg::Result<TransferId> upload_default(cfg::NodeId slave, std::uint16_t index, std::uint8_t sub,
                                         TimePoint now, Output& out,
                                         SdoTransferOptions options = {});
  cfg::Result<TransferId> download_default(cfg::NodeId slave, std::uint16_t index, std::uint8_t sub,
                                           std::vector<std::uint8_t> data, TimePoint now,
                                           Output& out, SdoTransferOptions options = {});

  // --- observation ---------------------------------------------------------------------------
  SrdRegistration registration() const { return registration_; }
  /// The client entry of the channel to the manager; nullopt unless Registered.
  std::optional<std::uint16_t> manager_channel() const;
  /// The channel of an established connection (as the manager wrote 1280h+ sub 1/2/3); nullopt
  /// when `client_index` holds none.
  std::optional<SdoClientConfig> connection(std::uint16_t client_index) const;
  /// The client entries holding established connections, in index order.
  std::vector<std::uint16_t> connections() const;
  SlaveNode& node() { return *node_; }
  const SlaveNode& node() const { return *node_; }

  /// Only create() can call this (Key is private).
  SdoRequestingDevice(Key, std::unique_ptr<SlaveNode> node, SrdOptions options);

 private:
  struct Pending {
    enum class What : std::uint8_t { Request, Release, Deregister };
    What what = What::Request;
    std::optional<cfg::NodeId> slave{};  // nullopt: Deregister (1F01h slave 0, all)
    std::uint16_t client_index = 0;
    SdoClient::TransferId transfer = 0;   // the 1F00h/1F01h download on the manager channel
    bool accepted = false;                // the download succeeded
    std::optional<TimePoint> deadline{};  // of the 1F10h confirmation
  };
  struct Channel {
    std::unique_ptr<SdoClient> client;
    // the SRD's TransferId of each transfer running or queued on this client
    std::map<SdoClient::TransferId, TransferId> transfers;
  };

  void observe(std::uint16_t index, std::uint8_t sub, TimePoint now);
  /// The node's frames and events into `out`; the writes the SRD acts on (1F10h, 1F11h, client
  /// entries sub 1/2), in the order the node took them.
  std::vector<cfg::ObjectAddress> take_node_output(SlaveNode::Output& node_out, Output& out);
  void process(std::span<const cfg::ObjectAddress> written, TimePoint now, Output& out);
  void on_state_written(cfg::sdo_manager::DynamicSdoState state, TimePoint now, Output& out);
  void on_client_entry_written(std::uint16_t client_index, TimePoint now, Output& out);
  void manager_results(const SdoClient::Output& results, TimePoint now, Output& out);
  void channel_results(std::uint32_t key, const SdoClient::Output& results, Output& out);
  cfg::Status send_to_manager(Pending pending, std::uint32_t word, std::uint16_t object,
                              TimePoint now, Output& out);
  cfg::Result<TransferId> start(std::uint32_t key, bool upload, std::uint16_t index,
                                std::uint8_t sub, std::vector<std::uint8_t> data, TimePoint now,
                                Output& out, const SdoTransferOptions& options);
  void drop_channel(std::uint32_t key, TimePoint now, Output& out);
  void forget_registration(TimePoint now, Output& out);
  void report(SrdEvent event, Output& out);
  std::uint32_t open_default(cfg::NodeId slave);
  /// The channel key of `slave`'s default SDO: above the 1280h-12FFh keys.
  static constexpr std::uint32_t default_channel(cfg::NodeId slave) { return 0x10000u + slave; }

  std::unique_ptr<SlaveNode> node_;
  SrdOptions options_;
  SrdRegistration registration_ = SrdRegistration::Unregistered;
  std::optional<TimePoint> registration_deadline_;
  std::optional<std::uint16_t> manager_index_;
  std::unique_ptr<SdoClient> manager_;
  std::optional<Pending> pending_;
  /// Established channels by key: 1280h-12FFh, or default_channel(slave).
  std::map<std::uint32_t, Channel> channels_;
  TransferId next_transfer_ = 1;
  /// The parts' outputs, emptied before each use and kept so that no call allocates them anew.
  /// `dropped` is apart from `manager`: a de-registration the manager confirms drops channels
  /// while the manager's results are being read.
  struct Scratch {
    SlaveNode::Output node;
    SdoClient::Output manager;
    SdoClient::Output channel;
    SdoClient::Output dropped;
  } scratch_;
};
static_assert(Engine<SdoRequestingDevice>);

}  // namespace nmt
