#include "cfg/optional_text.hpp"

#include <ostream>

namespace cfg {

std::ostream& operator<<(std::ostream& out, const OptionalText& text) {
  if (!text) return out << "nullopt";
  return out << '"' << *text << '"';
}

}  // namespace cfg
