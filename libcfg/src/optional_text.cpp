#include "cfg/optional_text.hpp"

#include <ostream>

#include "cfg/model_memory.hpp"

namespace cfg {

std::string& OptionalText::emplace_in(ModelArena& arena, std::string_view text) {
  release();
  // NOLINTNEXTLINE(performance-no-int-to-ptr): a tagged pointer (optional_text.hpp)
  text_ = reinterpret_cast<std::string*>(reinterpret_cast<std::uintptr_t>(arena.new_text(text)) |
                                         kInArena);
  return *get();
}

std::ostream& operator<<(std::ostream& out, const OptionalText& text) {
  if (!text) return out << "nullopt";
  return out << '"' << *text << '"';
}

}  // namespace cfg
