// The configuration manager's objects on the NMT master's SDO server (CiA DSP 302 v3.2.1 §6):
// 1F20h-1F25h served from a cfg::ConfigManager (MasterOptions::manager), and the one owner of
// 1F26h/1F27h (docs/master.md), as a process of its own. Private to the library.
//
// It owns its state: the master DCF's own 1F22h streams (the fallback of a node the manager
// holds nothing for), the entry whose file a read filled last (the dictionary keeps at most one
// copy of a stored file), and the stored entries an SDO write staged that wait for the driver
// (by ticket). It reaches the master only through ConfigurationStorePort: "is this node a
// slave", "does this device boot slaves now", "configure this slave" (1F25h 'conf') and
// "complete the held download with this ticket".
//
// No disk I/O in the engine (an SDO write is answered on the frame path; docs/master.md): a write
// of a stored entry is decided at once (cfg::ConfigManager::stage: checks and abort codes) and,
// with a store directory, reported as MasterEvent::PersistEntry into the output of the call the
// write runs in; the write hook answers WriteVerdict::hold(ticket), so the SDO server holds the
// confirmation. The driver writes the entry and calls entry_persisted(): the manager takes the
// value (commit) and the port completes the download, confirmed or aborted with 0800 0020h.
//
// A process with a port rather than a full nmt::Engine: it has no frames and no timers of its
// own. Its work is reached through the master's dictionary (hooks on 1F20h-1F27h, which the
// master's SDO server and dictionary() writes run) and through entry_persisted(), which the
// driver calls; so it has no on_frame/on_timer/next_deadline for the master to route to, and
// what it reports goes into the Output of the call it runs in (engine.hpp rule 6).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "cfg/config_manager.hpp"
#include "cfg/node_id.hpp"
#include "nmt/engine.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/slave/local_dictionary.hpp"

namespace nmt {

/// What the configuration manager's objects need of the NMT master, and nothing else.
class ConfigurationStorePort {
 public:
  using Output = Outbox<MasterEvent>;
  virtual ~ConfigurationStorePort() = default;
  /// `node` is one of the master's slaves (1F81h bit 0, not the master itself).
  virtual bool is_slave(cfg::NodeId node) const = 0;
  /// As request NMT: only the active master boots slaves (1F80h bit 0, and no other flying
  /// master is the active one).
  virtual bool boots_slaves() const = 0;
  /// DSP 302 §6.4 'conf': boot `node` again, as boot_slave() of the application does, with the
  /// configuration downloaded even where 1020h matches ("request re-configuration").
  virtual void configure(cfg::NodeId node, TimePoint now, Output& out) = 0;
  /// The SDO download held under `ticket` (WriteVerdict::hold) is confirmed (SdoAbort::None) or
  /// aborted with `code`; nothing when no download is held under it (a dictionary() write).
  virtual void complete_download(std::uint64_t ticket, SdoAbort code, Output& out) = 0;
};

/// The configuration manager's objects 1F20h-1F27h (see the top).
class ConfigurationStoreObjects {
 public:
  using Event = MasterEvent;
  using Output = Outbox<MasterEvent>;

  /// Serves its objects from `dict` (the master's dictionary); both must outlive it. Without a
  /// `manager` it adds nothing, and 1F22h/1F26h/1F27h are the dictionary's own values.
  ConfigurationStoreObjects(LocalDictionary& dict, ConfigurationStorePort& port,
                            std::shared_ptr<cfg::ConfigManager> manager,
                            std::shared_ptr<const ConfigurationSource> configurations)
      : dict_(dict),
        port_(port),
        manager_(std::move(manager)),
        configurations_(std::move(configurations)) {}
  // Its hooks in the dictionary point here.
  ConfigurationStoreObjects(const ConfigurationStoreObjects&) = delete;
  ConfigurationStoreObjects& operator=(const ConfigurationStoreObjects&) = delete;

  /// Adds 1F20h-1F25h served from the manager and its hooks; nothing without one. Reads the
  /// configuration source's DCFs here, once (see source_dcfs_).
  void install();

  /// The driver made the entry of `ticket` durable (or failed to, `result`): the update taken
  /// on success and the held download completed through the port (0800 0020h on failure). An
  /// unknown or completed ticket changes nothing.
  void entry_persisted(std::uint64_t ticket, const cfg::Status& result, TimePoint now, Output& out);

  /// 1F26h/1F27h of `node`: the manager's when it holds anything for the node (one owner,
  /// docs/master.md), else the dictionary's.
  cfg::ConfigurationStamp expected_configuration(cfg::NodeId node) const;
  /// The configuration to download to `node` (CiA 302-2 §3.5 d): the manager's, the source's,
  /// or the master's own 1F22h.
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const;

 private:
  /// A read's value, or the abort that answers it.
  struct StoreValue {
    SdoAbort abort = SdoAbort::None;
    std::vector<std::uint8_t> data;
  };

  /// The manager's 1F26h/1F27h of `node` when it holds anything for the node (a stamp or a
  /// configuration); nullopt without a manager or when it holds nothing (the dictionary's
  /// values apply).
  std::optional<cfg::ConfigurationStamp> stored_stamp(cfg::NodeId node) const;
  SdoAbort read(std::uint16_t index, std::uint8_t sub);
  /// 1F20h-1F22h of a node the manager stores no configuration for: the configuration source's
  /// concise DCF and DCF, else the master DCF's own 1F22h (docs/master.md). nullopt: the
  /// manager's answer applies.
  std::optional<StoreValue> unstored_read(std::uint16_t index, cfg::NodeId node) const;
  /// 1F25h: the nodes with a configuration that is not stored join the manager's answer.
  void add_unstored_configurations(std::uint8_t sub, cfg::ConfigWrite& written) const;
  /// An SDO write of 1F20h-1F27h: decided by the manager; a change of a stored entry is held
  /// for persist_entry() (see docs/master.md).
  WriteVerdict write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                     TimePoint now, Output* out);
  /// Takes `update` at once (no store directory), or reports it as PersistEntry into `out` and
  /// holds the write's confirmation (0800 0022 without an output: nobody to ask).
  WriteVerdict persist_entry(cfg::StoreUpdate update, TimePoint now, Output* out);
  /// 1F25h: boot (and download to) every slave the manager named (0800 0022 without an output).
  SdoAbort configure_slaves(std::uint8_t sub, const std::vector<cfg::NodeId>& nodes, TimePoint now,
                            Output* out);
  /// The master's own 1F22h stream of `node` (the DCF's value); empty when none.
  std::span<const std::uint8_t> own_concise_dcf(cfg::NodeId node) const;

  LocalDictionary& dict_;
  ConfigurationStorePort& port_;
  std::shared_ptr<cfg::ConfigManager> manager_;
  std::shared_ptr<const ConfigurationSource> configurations_;
  /// With a manager: the master DCF's own 1F22h streams by node-ID, used for a node the manager
  /// holds no configuration for.
  std::map<std::uint8_t, std::vector<std::uint8_t>> file_concise_;
  /// With a manager and a configuration source: the source's DCF texts by node-ID (what 1F20h
  /// and 1F21h of a node the manager stores nothing for answer), or why one cannot be read;
  /// absent where the source has none. Read once in install(): a source may read them from
  /// disk, which an SDO read, answered on the frame path, must not wait for.
  std::map<cfg::NodeId, cfg::Result<std::string>> source_dcfs_;
  /// The entry whose value a read of 1F20h/1F22h/1F23h filled last (emptied at the next read, so
  /// the dictionary keeps at most one copy of a stored file).
  std::optional<std::pair<std::uint16_t, std::uint8_t>> read_entry_;
  /// Entries an SDO write staged that wait for the driver's entry_persisted(), by ticket.
  std::map<std::uint64_t, std::shared_ptr<cfg::StoreUpdate>> persists_;
  std::uint64_t last_persist_ticket_ = 0;
};

}  // namespace nmt
