#include "nmt/lss/lss_search.hpp"

namespace nmt {

LssAddressSearch::LssAddressSearch(std::uint32_t vendor_id, std::uint32_t product_code) {
  LssAddressRange all;
  all.vendor_id = vendor_id;
  all.product_code = product_code;
  pending_.push_back(all);
}

std::optional<LssAddressRange> LssAddressSearch::next() const {
  if (pending_.empty()) return std::nullopt;
  return pending_.back();
}

void LssAddressSearch::answered(bool any) {
  if (pending_.empty()) return;
  ++requests_;
  const LssAddressRange range = pending_.back();
  pending_.pop_back();
  if (!any) return;
  // Halve the revision range first, then the serial number range; the upper half goes below
  // the lower one on the stack, so addresses are found in ascending order.
  LssAddressRange low = range;
  LssAddressRange high = range;
  if (range.revision_low != range.revision_high) {
    const std::uint32_t middle =
        range.revision_low + (range.revision_high - range.revision_low) / 2;
    low.revision_high = middle;
    high.revision_low = middle + 1;
  } else if (range.serial_low != range.serial_high) {
    const std::uint32_t middle = range.serial_low + (range.serial_high - range.serial_low) / 2;
    low.serial_high = middle;
    high.serial_low = middle + 1;
  } else {
    found_.push_back(
        LssAddress{range.vendor_id, range.product_code, range.revision_low, range.serial_low});
    return;
  }
  pending_.push_back(high);
  pending_.push_back(low);
}

}  // namespace nmt
