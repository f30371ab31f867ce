// The runtime object dictionary of one node: every entry of a device description with its
// attributes and its current value as bytes. The SDO server reads and writes it through the
// checked `read`/`write` (CiA 301 access and value rules, answering with abort codes); the device
// model uses the unchecked accessors and hooks. No I/O, no clock: the time of an access is given
// by the caller and handed to the hooks.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <type_traits>
#include <typeinfo>
#include <vector>

#include "cfg/cob_id.hpp"
#include "cfg/data_type.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/result.hpp"
#include "cfg/value.hpp"
#include "cfg/write_acceptance.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_abort.hpp"

namespace nmt {

/// One value-carrying entry (index, sub-index) of the dictionary: its attributes and current
/// value, as the write rules of libcfg (cfg/write_acceptance.hpp) see a device's entries.
using DictionaryEntry = cfg::DeviceEntry;

/// A write hook's answer: accept (SdoAbort::None, the default), refuse with a code, or accept
/// and hold the confirmation of the SDO download until the dictionary's owner completes it
/// under `held` (SdoServer::complete_download): the master's 1F20h-1F27h, whose confirmation
/// leaves once the entry is durable (docs/master.md, "Configuration manager"). A plain SdoAbort
/// converts to it, so a hook that never holds returns SdoAbort. A hook that holds must run after
/// every hook that may refuse the same entry: a later refusal does not undo what the holding hook
/// started.
struct WriteVerdict {
  SdoAbort abort = SdoAbort::None;
  /// The ticket of a held confirmation; nullopt: confirm at once.
  std::optional<std::uint64_t> held;

  WriteVerdict() = default;
  WriteVerdict(SdoAbort code)
      : abort(code) {}  // NOLINT(google-explicit-constructor): a hook's code
  static WriteVerdict hold(std::uint64_t ticket) {
    WriteVerdict verdict;
    verdict.held = ticket;
    return verdict;
  }
};

/// The output of the engine call a dictionary access runs in, handed to the hooks: what a hook
/// reports or sends goes into that call's output (engine.hpp rule 6), never into a list kept for
/// a later call. A typed reference to the owner's Outbox<Event> (the slave node's, the
/// master's); empty for an access outside any engine call (a program setting up a dictionary
/// before it runs), where a hook has no output and reports nothing.
class HookOutput {
 public:
  HookOutput() = default;
  template <class Event>
  HookOutput(Outbox<Event>& out)  // NOLINT(google-explicit-constructor): the call's output
      : out_(&out), type_(&typeid(Outbox<Event>)) {}

  /// The output as the owner's Outbox<Event>; nullptr when empty or of another engine's type.
  template <class Event>
  Outbox<Event>* as() const {
    if (type_ == nullptr || *type_ != typeid(Outbox<Event>)) return nullptr;
    return static_cast<Outbox<Event>*>(out_);
  }

 private:
  void* out_ = nullptr;
  const std::type_info* type_ = nullptr;
};

class LocalDictionary {
 public:
  /// Default max_size of variable-size entries (strings, DOMAIN): 1 MiB.
  static constexpr std::size_t kDefaultMaxVariableSize = cfg::kDefaultMaxVariableSize;

  /// Called by write() after all dictionary checks passed and before the value is stored, with
  /// the time of the write. A code other than SdoAbort::None rejects the write with that code
  /// (the value stays); WriteVerdict::hold accepts it and holds its SDO confirmation
  /// (write_download()). `out`: the output of the call the write runs in (HookOutput).
  using WriteHook = std::function<WriteVerdict(std::uint16_t index, std::uint8_t sub,
                                               std::span<const std::uint8_t> data, TimePoint now,
                                               HookOutput out)>;
  /// Called by write() after a value was stored (not by the unchecked setters), with the time of
  /// the write and the output of the call it runs in.
  using WriteObserver =
      std::function<void(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                         TimePoint now, HookOutput out)>;
  /// Called by read() after the access check, before the value is copied, with the time of the
  /// read: it may refresh the value with set_bytes() or refuse the read with a code (e.g.
  /// NoDataAvailable).
  using ReadHook =
      std::function<SdoAbort(std::uint16_t index, std::uint8_t sub, TimePoint now, HookOutput out)>;
  /// Called by check_write() (so by write() and by the SDO server) when the size of a write is
  /// known: an SDO download's indicated size at its initiate request, the size received so far
  /// while segments of a download without one arrive, or write()'s data. Runs after the
  /// existence and access checks, before the size check against the entry: a result other than
  /// SdoAbort::None refuses the write with that code before the data is buffered (e.g. 0504 0005
  /// for a value the device has no memory for).
  using SizeHook = std::function<SdoAbort(std::uint16_t index, std::uint8_t sub, std::size_t size)>;
  /// Where add_*_hook puts a hook among those already there: hooks run in that order and the
  /// first refusal wins.
  enum class HookPosition : std::uint8_t { Last, First };

  LocalDictionary() = default;

  /// Builds the dictionary of node `node_id` (1..127) from a device description: every
  /// sub-object becomes an entry whose value is ParameterValue, else DefaultValue, else zeros
  /// of the type's size (empty for variable-size types), parsed with cfg::parse_value and
  /// $NODEID resolved; LowLimit/HighLimit likewise. Fails with a message naming the entry
  /// ("object 1017h sub 00h: ...") when a value or limit does not parse.
  static cfg::Result<LocalDictionary> from_device(const cfg::DeviceDescription& device,
                                                  cfg::NodeId node_id);

  /// The node-ID the values were resolved for; nullopt for a dictionary built empty.
  std::optional<cfg::NodeId> node_id() const { return node_id_; }
  /// The node got another node-ID (LSS, CiA 305): its values are copied in from a dictionary
  /// built for `node_id` by the owner; this only changes what node_id() says (the default SDO
  /// channel of a dictionary without 1200h follows it).
  void set_node_id(cfg::NodeId node_id) { node_id_ = node_id; }

  // --- SDO side: checked, answers with CiA 301 abort codes ----------------------------------

  /// Reads the value for an SDO upload at `now` into `out` (replaced). Aborts:
  /// ObjectDoesNotExist (no entry at `index`), SubIndexDoesNotExist, ReadOfWriteOnly (wo), or a
  /// read hook's code. `hooks`: the output of the engine call the read runs in (HookOutput).
  SdoAbort read(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t>& out,
                TimePoint now, HookOutput hooks = {}) const;

  /// Writes a value from an SDO download. Checks in this order, each with its abort:
  /// object exists (ObjectDoesNotExist), sub-index exists (SubIndexDoesNotExist), writable
  /// (WriteOfReadOnly for ro/const), size (fixed types: LengthTooHigh / LengthTooLow;
  /// variable types: LengthTooHigh above max_size), value (BOOLEAN other than 0/1:
  /// ValueRangeExceeded; HighLimit < LowLimit: MaxLessThanMin; above HighLimit: ValueTooHigh;
  /// below LowLimit: ValueTooLow), then the write hooks in their order. On None the value is
  /// stored and the observers are called. `now`: the time of the write, for the hooks; `out`:
  /// the output of the engine call it runs in, where hooks report (HookOutput; an owner whose
  /// hooks start work, e.g. the master, documents what it needs there).
  SdoAbort write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                 TimePoint now, HookOutput out = {});
  /// write() for an SDO download: also says whether a write hook holds the confirmation (the
  /// value is stored all the same; the hook's owner completes the download later with success
  /// or an abort). write() ignores a hold: its caller has no confirmation to send.
  WriteVerdict write_download(std::uint16_t index, std::uint8_t sub,
                              std::span<const std::uint8_t> data, TimePoint now,
                              HookOutput out = {});

  /// The checks write() does before seeing the data: existence, access, and (when the size is
  /// known) the size hooks, then the size (cfg::check_entry_access). The SDO server uses it to
  /// refuse a download at its initiate request, and as the data of one without an indicated
  /// size grows.
  SdoAbort check_write(std::uint16_t index, std::uint8_t sub,
                       std::optional<std::size_t> size) const;

  // A hook that reports nothing may leave out the HookOutput parameter.
  template <class Hook>
  void add_write_hook(Hook hook, HookPosition where = HookPosition::Last) {
    write_hooks_.insert(where == HookPosition::First ? write_hooks_.begin() : write_hooks_.end(),
                        with_output<WriteHook, std::span<const std::uint8_t>>(std::move(hook)));
  }
  void add_size_hook(SizeHook hook) { size_hooks_.push_back(std::move(hook)); }
  template <class Observer>
  void add_write_observer(Observer observer) {
    observers_.push_back(
        with_output<WriteObserver, std::span<const std::uint8_t>>(std::move(observer)));
  }
  template <class Hook>
  void add_read_hook(Hook hook, HookPosition where = HookPosition::Last) {
    read_hooks_.insert(where == HookPosition::First ? read_hooks_.begin() : read_hooks_.end(),
                       with_output<ReadHook>(std::move(hook)));
  }

  // --- device model side: unchecked (no access, size or range checks, no hooks) ------------

  /// Attributes and value of an entry; nullptr when absent.
  const DictionaryEntry* entry(std::uint16_t index, std::uint8_t sub) const;
  /// True when any sub-index of `index` exists.
  bool has_object(std::uint16_t index) const;
  /// The current bytes; nullopt when the entry is absent. The span is valid until the entry's
  /// value changes.
  std::optional<std::span<const std::uint8_t>> get_bytes(std::uint16_t index,
                                                         std::uint8_t sub) const;
  /// The value as a little-endian unsigned number (first up to 8 bytes; BOOLEAN and integer
  /// types). nullopt when absent or when the entry is not BOOLEAN/integer.
  std::optional<std::uint64_t> get_unsigned(std::uint16_t index, std::uint8_t sub) const;
  /// The value as a CiA 301 COB-ID word (1200h-12FFh sub 1/2, 1014h, PDO sub 1); nullopt when
  /// absent, not an integer, or above 32 bits.
  std::optional<cfg::CobId> get_cob_id(std::uint16_t index, std::uint8_t sub) const;
  /// The value decoded as its basic type; nullopt when absent, of unknown type or undecodable.
  std::optional<cfg::Value> get_value(std::uint16_t index, std::uint8_t sub) const;
  /// Replaces the bytes as they are. False when the entry is absent.
  bool set_bytes(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data);
  /// Stores `value` little-endian in the entry's fixed size (truncating higher bytes). False
  /// when absent or not of a fixed-size type.
  bool set_unsigned(std::uint16_t index, std::uint8_t sub, std::uint64_t value);
  /// Changes the largest size a write may store in a variable-size entry. False when absent or
  /// of a fixed-size type.
  bool set_max_size(std::uint16_t index, std::uint8_t sub, std::size_t max_size);
  /// Adds or replaces an entry (objects the device model implements beyond its device file).
  /// A max_size of 0 is replaced by the default for the entry's type.
  void insert(DictionaryEntry entry);

  /// All entries in (index, sub-index) order.
  const std::map<std::uint32_t, DictionaryEntry>& entries() const { return entries_; }
  /// The key of entries(): index << 8 | sub (cfg::ObjectAddress::key()).
  static constexpr std::uint32_t key(std::uint16_t index, std::uint8_t sub) {
    return cfg::ObjectAddress{index, sub}.key();
  }

 private:
  DictionaryEntry* find(std::uint16_t index, std::uint8_t sub);
  // A hook as the stored std::function type; one without the HookOutput parameter is wrapped.
  template <class Stored, class... Data, class Hook>
  static Stored with_output(Hook hook) {
    if constexpr (std::is_invocable_v<Hook&, std::uint16_t, std::uint8_t, Data..., TimePoint,
                                      HookOutput>) {
      return Stored(std::move(hook));
    } else {
      return Stored([hook = std::move(hook)](std::uint16_t index, std::uint8_t sub, Data... data,
                                             TimePoint now, HookOutput) mutable {
        return hook(index, sub, data..., now);
      });
    }
  }

  std::optional<cfg::NodeId> node_id_;
  cfg::DeviceEntries entries_;
  std::vector<WriteHook> write_hooks_;
  std::vector<SizeHook> size_hooks_;
  std::vector<WriteObserver> observers_;
  std::vector<ReadHook> read_hooks_;
};

}  // namespace nmt
