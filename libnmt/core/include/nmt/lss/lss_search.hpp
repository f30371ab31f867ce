// Finding every LSS device of one product, configured or not, with identify remote slave
// (CiA 305; nmt/lss/lss.hpp has the protocol and its sources): the binary search lely-core calls
// Slowscan (src/co/lss.c, co_lss_slowscan_req). Identify remote slave (46h-4Bh) names the
// vendor-ID and product code exactly and ranges of revision and serial number, and every device
// inside answers 4Fh whatever its node-ID; so a range that is answered is halved (revision
// first, then serial number) until it holds one address. Fastscan finds unconfigured devices
// only; this finds all, but only of the vendor and product asked for.
//
// Sans-I/O: the driver sends identify_remote_slaves(next()) with an LssMaster and tells the
// search whether any device answered (Done) or none (NotFound):
//   nmt::LssAddressSearch search(0x7E57C0DE, 0x305);
//   while (auto range = search.next()) search.answered(identify(*range));
//   search.found();   // ascending LSS addresses
// Cost: one request for the whole range, then two per halving down to each device (64 per
// device, fewer where devices share the upper bits): at most 1 + 128 per device, each lasting
// the master's scan step.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "nmt/lss/lss.hpp"
#include "nmt/lss/lss_master.hpp"

namespace nmt {

class LssAddressSearch {
 public:
  LssAddressSearch(std::uint32_t vendor_id, std::uint32_t product_code);

  /// The range to identify next; nullopt when the search is over.
  std::optional<LssAddressRange> next() const;
  /// The outcome of identifying next(): true when at least one device answered.
  void answered(bool any);
  /// The addresses found so far, ascending.
  const std::vector<LssAddress>& found() const { return found_; }
  /// Identify requests answered() was told about.
  std::uint32_t requests() const { return requests_; }

 private:
  std::vector<LssAddressRange> pending_;  ///< a stack: the lowest range on top
  std::vector<LssAddress> found_;
  std::uint32_t requests_ = 0;
};

}  // namespace nmt
