// The object lists of CiA 306 §4.6.2: [MandatoryObjects], [OptionalObjects],
// [ManufacturerObjects], checked against the object sections.
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "device_reader.hpp"

namespace cfg::detail::reader {

void Reader::list_key(std::string_view key, std::string_view value, int line) {
  ListState& list = lists_[static_cast<std::size_t>(cur_.list)];
  if (iequals(key, "SupportedObjects")) {
    if (list.supported) {
      warn(line, where() + "SupportedObjects is given a second time; the later value is used");
    }
    list.supported = number(key, value, line, 0xFFFF);
    list.supported_line = line;
    return;
  }
  auto n = parse_number(key);
  if (!n || n->value == 0 || n->h_suffix) {
    warn(line, where() + "key " + std::string(key) +
                   " is neither SupportedObjects nor an entry number; ignored");
    return;
  }
  if (auto index = number(key, value, line, 0xFFFF)) {
    list.entries.emplace_back(static_cast<std::uint16_t>(*index), line);
  }
}

void Reader::check_object_lists() {
  static constexpr std::array<std::string_view, 3> kNames = {"MandatoryObjects", "OptionalObjects",
                                                             "ManufacturerObjects"};
  static constexpr std::array<ObjectList, 3> kKinds = {ObjectList::Mandatory, ObjectList::Optional,
                                                       ObjectList::Manufacturer};
  std::map<std::uint16_t, int> listed;  // index -> line
  bool any_list = false;
  for (std::size_t i = 0; i < 3; ++i) {
    const ListState& list = lists_[i];
    if (!list.present) continue;
    any_list = true;
    const std::string sec = "[" + std::string(kNames[i]) + "]";
    if (!list.supported) {
      warn(list.line, sec + " has no SupportedObjects");
    } else if (*list.supported != list.entries.size()) {
      warn(list.supported_line, sec + " SupportedObjects " + std::to_string(*list.supported) +
                                    " but " + std::to_string(list.entries.size()) +
                                    " objects are listed; the listed objects are used");
    }
    for (const auto& [index, line] : list.entries) {
      auto [it, inserted] = listed.emplace(index, line);
      if (!inserted) {
        warn(line, sec + " lists " + object_name(index) + " again (first at line " +
                       std::to_string(it->second) + ")");
        continue;
      }
      if (strict_ && object_list_for(index) != kKinds[i]) {
        error(line, sec + " lists " + object_name(index) + ", which belongs in [" +
                        std::string(to_string(object_list_for(index))) + "]");
      }
      if (!model_.object(index)) {
        warn(line, sec + " lists " + object_name(index) + " but the file has no " +
                       section_of(index) + " section; no such object");
      }
    }
  }
  if (!any_list) {
    if (!model_.objects.empty()) {
      warn(0,
           "the file has no object lists ([MandatoryObjects], [OptionalObjects], "
           "[ManufacturerObjects]); objects are taken from their sections");
    }
    return;
  }
  // One warning for all of them: some files leave out whole groups (all PDO objects).
  std::vector<const Object*> unlisted;
  for (const auto& [index, obj] : model_.objects) {
    if (!listed.count(index)) unlisted.push_back(&obj);
  }
  if (!unlisted.empty()) {
    constexpr std::size_t kShown = 8;
    std::string names;
    for (std::size_t i = 0; i < unlisted.size() && i < kShown; ++i) {
      names += (i ? ", " : "") + section_of(unlisted[i]->index);
    }
    if (unlisted.size() > kShown) {
      names += " and " + std::to_string(unlisted.size() - kShown) + " more";
    }
    warn(unlisted.front()->line, names + (unlisted.size() == 1 ? " is" : " are") +
                                     " in no object list ([MandatoryObjects], [OptionalObjects], "
                                     "[ManufacturerObjects]); kept");
  }
}

}  // namespace cfg::detail::reader
