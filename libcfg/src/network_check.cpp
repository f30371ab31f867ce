#include "cfg/network_check.hpp"

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/cob_id.hpp"
#include "cfg/data_type.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "cfg/value.hpp"

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

class Checker {
 public:
  explicit Checker(Diagnostics& diagnostics) : diagnostics_(diagnostics) {}

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
        mapping_of(m, pdo);
      }
    }
  }

  // CiA 301 §7.2.2: one producer per PDO; consumers without a producer are only noted.
  void clashes() {
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
  void mapping_of(const Member& m, const object::PdoIndices& pdo) {
    if (m.dcf == nullptr) return;  // a concise DCF alone says nothing about mappability
    const Object* mapping = m.dcf->object(pdo.mapping_index);
    if (mapping == nullptr) return;
    const auto count = value_of(m, pdo.mapping_index, 0);
    for (const auto& [sub_index, sub] : mapping->subs) {
      if (sub_index == 0) continue;
      if (count && sub_index > count->value) break;
      const auto entry = value_of(m, pdo.mapping_index, sub_index);
      if (!entry || entry->value == 0) continue;
      check_entry(m, pdo, sub_index, *entry);
    }
  }

  void check_entry(const Member& m, const object::PdoIndices& pdo, std::uint8_t entry_sub,
                   const Located& entry) {
    const auto index = static_cast<std::uint16_t>(entry.value >> 16);
    const auto sub_index = static_cast<std::uint8_t>(entry.value >> 8);
    const unsigned bits = entry.value & 0xFFU;
    const std::string where = m.label + " " + pdo_name(pdo) + " " +
                              to_string(ObjectAddress{pdo.mapping_index, entry_sub}) + " = " +
                              hex(entry.value, 8) + " maps " +
                              to_string(ObjectAddress{index, sub_index});
    // CiA 301 §7.4.7.1: an RPDO may map a data type index (0001h-0007h) as a dummy entry.
    if (pdo.receive && index >= 0x0001 && index <= 0x0007) return;
    const SubObject* target = m.dcf->sub(index, sub_index);
    if (target == nullptr) {
      diagnostics_.add(m.file, entry.line, Severity::Error,
                       where + ", which the DCF does not have (the device aborts 0602 0000)");
      return;
    }
    if (!target->pdo_mapping) {
      diagnostics_.add(m.file, entry.line, Severity::Error,
                       where + ", which is not mappable: PDOMapping=0 at " +
                           at(m.file, target->line) + " (the device aborts 0604 0041)");
      return;
    }
    // BOOLEAN may be mapped as one bit or as its byte; other fixed-size types with their size.
    if (const auto type = target->basic_type(); type && *type != DataType::Boolean) {
      const unsigned size_bits = data_type_info(*type).size_bytes * 8U;
      if (size_bits != 0 && size_bits != bits) {
        diagnostics_.add(m.file, entry.line, Severity::Warning,
                         where + " with " + std::to_string(bits) + " bits, but its type " +
                             std::string(data_type_info(*type).name) + " has " +
                             std::to_string(size_bits));
      }
    }
    if (pdo.receive ? !is_writable(target->access) : !is_readable(target->access)) {
      diagnostics_.add(
          m.file, entry.line, Severity::Warning,
          where + ", whose access type " + std::string(to_string(target->access)) +
              (pdo.receive ? " cannot be written by an RPDO" : " cannot be read for a TPDO"));
    }
  }

  Diagnostics& diagnostics_;
  // By COB-ID word of the identifier (frame format included).
  std::map<std::uint32_t, std::vector<Producer>> producers_;
  std::map<std::uint32_t, std::vector<Producer>> consumers_;
};

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
  for (const auto& m : members) checker.pdos_of(m);
  checker.clashes();
}

}  // namespace cfg
