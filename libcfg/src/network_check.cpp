#include "cfg/network_check.hpp"

#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/cob_id.hpp"
#include "cfg/data_type.hpp"
#include "cfg/hex.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "cfg/value.hpp"
#include "cfg/write_acceptance.hpp"

namespace cfg {
namespace {

// One device of the network as the checks see it.
struct Member {
  std::optional<NodeId> node_id;  // nullopt: a master DCF without a node-ID
  std::string label;              // "node 3 (axis_x)", "the master"
  std::string file;
  const DeviceDescription* dcf = nullptr;
  const std::vector<ObjectWrite>* writes = nullptr;
};

// A value as the node has it after its download, with where it was written.
struct Located {
  std::uint32_t value = 0;
  int line = 0;
};

// The last write of (index, sub) in `writes`, as an unsigned number of at most 4 bytes.
std::optional<std::uint32_t> written_value(const std::vector<ObjectWrite>& writes,
                                           std::uint16_t index, std::uint8_t sub) {
  std::optional<std::uint32_t> out;
  for (const auto& w : writes) {
    if (w.index == index && w.sub_index == sub && !w.data.empty() && w.data.size() <= 4) {
      out = static_cast<std::uint32_t>(load_le(w.data, w.data.size()));
    }
  }
  return out;
}

std::optional<Located> value_of(const Member& m, std::uint16_t index, std::uint8_t sub) {
  if (m.dcf == nullptr) {
    if (m.writes == nullptr) return std::nullopt;
    const auto v = written_value(*m.writes, index, sub);
    if (!v) return std::nullopt;
    return Located{*v, 0};
  }
  const SubObject* s = m.dcf->sub(index, sub);
  if (s == nullptr) return std::nullopt;
  const OptionalText& text = s->configured_value();
  if (!text || text->empty()) return std::nullopt;
  const auto node = m.node_id ? std::optional<std::uint8_t>(m.node_id->value()) : std::nullopt;
  auto parsed = parse_value(DataType::Unsigned32, *text, node);
  if (!parsed) return std::nullopt;  // the reader reported it
  const int line = s->parameter_value ? s->parameter_value_line : s->default_value_line;
  return Located{static_cast<std::uint32_t>(parsed->as_unsigned()), line != 0 ? line : s->line};
}

// "TPDO 1 (1800h)": PDOs are numbered from 1 in CiA 301.
std::string pdo_name(const object::PdoIndices& pdo) {
  const std::uint16_t first =
      pdo.receive ? object::kRpdoCommunicationFirst : object::kTpdoCommunicationFirst;
  return std::string(pdo.receive ? "RPDO " : "TPDO ") + std::to_string(pdo.comm_index - first + 1);
}

// "file.dcf:42", or the file alone when the line is unknown.
std::string at(const std::string& file, int line) {
  return line > 0 ? file + ":" + std::to_string(line) : file;
}

std::string can_id_text(CanId id) {
  return hex(id.id, id.extended ? 8 : 3);
}

struct Producer {
  const Member* member;
  object::PdoIndices pdo;
  int line;
};

// CiA 301 §7.3.5 (Table "restricted CAN-IDs"): 11-bit identifiers that no configurable
// communication object (PDO, SDO channel, ...) may use, and what each range is kept for.
struct RestrictedRange {
  std::uint32_t first;
  std::uint32_t last;
  std::string_view use;
};
constexpr RestrictedRange kRestrictedCanIds[] = {
    {0x000, 0x000, "NMT"},
    {0x001, 0x07F, "reserved"},
    {0x101, 0x180, "reserved"},
    {0x581, 0x5FF, "default SDO, server to client"},
    {0x601, 0x67F, "default SDO, client to server"},
    {0x6E0, 0x6FF, "reserved; 6E0h is the Dynamic SDO Request of DSP 302 §7.2.1"},
    {0x701, 0x77F, "NMT error control"},
    {0x780, 0x7FF, "reserved"},
};

// ", which CiA 301 restricts (581h-5FFh: default SDO, server to client)", or "" when `id` is
// free to use.
std::string restriction_of(CanId id) {
  if (id.extended) return {};
  for (const auto& r : kRestrictedCanIds) {
    if (id.id < r.first || id.id > r.last) continue;
    const std::string range = r.first == r.last
                                  ? hex_digits(r.first, 3) + "h"
                                  : hex_digits(r.first, 3) + "h-" + hex_digits(r.last, 3) + "h";
    return ", which CiA 301 restricts (" + range + ": " + std::string(r.use) + ")";
  }
  return {};
}

// An identifier a device of the network uses for something other than a PDO.
struct OtherUse {
  const Member* member;
  std::string what;  // "the EMCY COB-ID (1014h)"
  int line;
};

class Checker {
 public:
  explicit Checker(Diagnostics& diagnostics) : diagnostics_(diagnostics) {}

  // The identifiers `m` uses besides PDOs: its EMCY (1014h, CiA 301 §7.5.2.17), SYNC (1005h,
  // §7.5.2.5) and TIME (1012h, §7.5.2.13) COB-IDs, and the SDO manager's pool of COB-IDs for
  // dynamic SDO channels (1F02h, DSP 302 §7.2.3), each when the DCF configures it.
  void other_uses_of(const Member& m) {
    // 1014h: bit 31 set = no EMCY. 1005h/1012h: bits 30/31 say who produces or consumes; the
    // identifier is in use on the bus either way.
    const auto add = [&](std::uint16_t index, std::uint8_t sub, std::uint32_t ignored_bits,
                         const std::string& what) {
      const auto cob = value_of(m, index, sub);
      if (!cob) return;
      const auto id = usable_can_id(CobId::from_word(cob->value & ~ignored_bits));
      if (id) other_uses_[CobId::of(*id).word()].push_back({&m, what, cob->line});
    };
    add(object::kCobIdEmcy, 0, 0, "the EMCY COB-ID (" + object_name(object::kCobIdEmcy) + ")");
    add(object::kCobIdSync, 0, kCobIdInvalidBit | kCobIdBit30,
        "the SYNC COB-ID (" + object_name(object::kCobIdSync) + ")");
    add(object::kCobIdTime, 0, kCobIdInvalidBit | kCobIdBit30,
        "the TIME COB-ID (" + object_name(object::kCobIdTime) + ")");
    const auto pool = value_of(m, object::kSdoManagerCobIds, 0);
    for (std::uint32_t sub = 1; pool && sub <= pool->value && sub <= 0xFF; ++sub) {
      const auto s = static_cast<std::uint8_t>(sub);
      const auto cob = value_of(m, object::kSdoManagerCobIds, s);
      // Bit 30 (in use) is the manager's own bookkeeping.
      const auto id =
          cob ? usable_can_id(CobId::from_word(cob->value & ~kCobIdBit30)) : std::nullopt;
      if (!id) continue;
      const std::string what = to_string(ObjectAddress{object::kSdoManagerCobIds, s}) +
                               " (a COB-ID of the SDO manager's pool for dynamic SDO channels)";
      if (const auto restricted = restriction_of(*id); !restricted.empty()) {
        std::string message = m.label + "'s ";
        message += what;
        message += " is CAN-ID " + can_id_text(*id) + restricted;
        diagnostics_.add(m.file, cob->line, Severity::Error, message);
      }
      other_uses_[CobId::of(*id).word()].push_back({&m, what, cob->line});
    }
  }

  void pdos_of(const Member& m) {
    for (std::uint16_t n = 0; n < object::kPdoCount; ++n) {
      for (const bool receive : {false, true}) {
        const std::uint16_t comm = static_cast<std::uint16_t>(
            (receive ? object::kRpdoCommunicationFirst : object::kTpdoCommunicationFirst) + n);
        const object::PdoIndices pdo = *object::pdo_indices_of(comm);
        if (m.dcf != nullptr && m.dcf->object(comm) == nullptr &&
            m.dcf->object(pdo.mapping_index) == nullptr) {
          continue;
        }
        if (const auto cob = value_of(m, comm, 1)) {
          if (const auto id = usable_can_id(CobId::from_word(cob->value))) {
            (receive ? consumers_ : producers_)[CobId::of(*id).word()].push_back(
                {&m, pdo, cob->line});
          }
        }
      }
    }
  }

  // CiA 301 §7.2.2: one producer per PDO; consumers without a producer are only noted.
  // CiA 301 §7.3.5: no PDO on a restricted CAN-ID. A TPDO on an identifier another object of
  // the network uses (EMCY, SYNC, TIME, the SDO manager's pool) is a second producer: an error;
  // an RPDO on one takes those frames for PDOs: a warning.
  void clashes() {
    for (const bool receive : {false, true}) {
      for (const auto& [word, list] : receive ? consumers_ : producers_) {
        const CanId id = CobId::from_word(word).can_id();
        const std::string restricted = restriction_of(id);
        const auto other = other_uses_.find(word);
        for (const Producer& p : list) {
          const std::string pdo =
              p.member->label + " " + pdo_name(p.pdo) + " (" + object_name(p.pdo.comm_index) +
              " sub 01h) " + (receive ? "receives" : "transmits") + " CAN-ID " + can_id_text(id);
          if (!restricted.empty()) {
            diagnostics_.add(p.member->file, p.line, Severity::Error, pdo + restricted);
          }
          if (other == other_uses_.end()) continue;
          for (const OtherUse& o : other->second) {
            diagnostics_.add(p.member->file, p.line, receive ? Severity::Warning : Severity::Error,
                             pdo + ", " + o.what + " of " + o.member->label + " (" +
                                 at(o.member->file, o.line) + ")");
          }
        }
      }
    }
    for (const auto& [word, list] : producers_) {
      const CanId id = CobId::from_word(word).can_id();
      for (std::size_t i = 1; i < list.size(); ++i) {
        const Producer& first = list.front();
        const Producer& p = list[i];
        diagnostics_.add(p.member->file, p.line, Severity::Error,
                         "COB-ID clash: " + p.member->label + " " + pdo_name(p.pdo) + " (" +
                             object_name(p.pdo.comm_index) + " sub 01h) transmits CAN-ID " +
                             can_id_text(id) + ", as " + first.member->label + " " +
                             pdo_name(first.pdo) + " does (" + at(first.member->file, first.line) +
                             ")");
      }
    }
    for (const auto& [word, list] : consumers_) {
      if (producers_.contains(word)) continue;
      const CanId id = CobId::from_word(word).can_id();
      for (const Producer& c : list) {
        diagnostics_.add(c.member->file, c.line, Severity::Note,
                         c.member->label + " " + pdo_name(c.pdo) + " (" +
                             object_name(c.pdo.comm_index) + " sub 01h) receives CAN-ID " +
                             can_id_text(id) +
                             ", which no TPDO of the network transmits (a device outside the "
                             "description may)");
      }
    }
  }

 private:
  Diagnostics& diagnostics_;
  // By COB-ID word of the identifier (frame format included).
  std::map<std::uint32_t, std::vector<Producer>> producers_;
  std::map<std::uint32_t, std::vector<Producer>> consumers_;
  std::map<std::uint32_t, std::vector<OtherUse>> other_uses_;
};

// A master DCF alone configures node X from its 1F20h/1F22h sub X (network.hpp): a slave the
// master boots (1F81h bits 0 and 2, CiA 302-2 Table 19/20) whose entries name no file gets no
// configuration at all, which a generator that left the entry empty rarely means.
void slaves_without_configuration(const Network& network, Diagnostics& diagnostics) {
  if (!network.master_from_file || network.master_file != network.file) return;
  const DeviceDescription& master = network.master;
  const auto names_file = [&master](std::uint16_t index, std::uint8_t x) {
    const SubObject* s = master.sub(index, x);
    return s != nullptr && ((s->download_file && !s->download_file->empty()) ||
                            (s->upload_file && !s->upload_file->empty()));
  };
  const Member self{std::nullopt, "the master", network.master_file, &master, nullptr};
  for (unsigned x = kMinNodeId; x <= kMaxNodeId; ++x) {
    const auto sub = static_cast<std::uint8_t>(x);
    const auto assignment = value_of(self, object::kSlaveAssignment, sub);
    if (!assignment) continue;
    const SlaveAssignment bits{assignment->value};
    if (!bits.is_slave() || !bits.boot_slave()) continue;
    if (names_file(object::kStoreDcf, sub) || names_file(object::kConciseDcf, sub)) continue;
    const std::string digits = hex_digits(x, 2);
    const std::string node = std::to_string(x);
    diagnostics.add(network.master_file, assignment->line, Severity::Warning,
                    "1F81h sub " + digits + "h: node " + node +
                        " is a slave the master boots, but there is no configuration for node " +
                        node + " (1F22h sub " + digits + "h empty): neither 1F22h nor 1F20h sub " +
                        digits + "h names a file, so nothing is downloaded to it");
  }
}

}  // namespace

void check_network(const Network& network, Diagnostics& diagnostics) {
  std::vector<Member> members;
  members.reserve(network.nodes.size() + 1);
  if (network.master_from_file) {
    std::optional<NodeId> id = network.master_node_id;
    if (!id) {
      if (const auto own = network.master.node_id()) id = NodeId::from(*own);
    }
    members.push_back({id, "the master", network.master_file, &network.master, nullptr});
  }
  for (const auto& node : network.nodes) {
    std::string label = "node " + std::to_string(node.node_id.value());
    if (!node.name.empty()) label += " (" + node.name + ")";
    members.push_back(
        {node.node_id, std::move(label), node.file, node.dcf ? &*node.dcf : nullptr, &node.writes});
  }
  Checker checker(diagnostics);
  for (const auto& m : members) {
    checker.other_uses_of(m);
    checker.pdos_of(m);
  }
  checker.clashes();
  // Each node's own writes, as `cfgmgr check` runs a single DCF's (write_acceptance.hpp).
  for (const auto& m : members) {
    if (m.dcf == nullptr || m.writes == nullptr || !m.node_id) continue;
    check_download(*m.dcf, *m.node_id, *m.writes, m.file, m.label + ": ", diagnostics);
  }
  slaves_without_configuration(network, diagnostics);
}

}  // namespace cfg
