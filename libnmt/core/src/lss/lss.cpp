#include "nmt/lss/lss.hpp"

#include <array>
#include <cassert>
#include <cstdio>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"

namespace nmt {

namespace {
// Both part() overloads: the same selection, const or not.
template <class Address>
auto& part_of(Address& a, int sub) {
  assert(sub >= 0 && sub <= 3);
  switch (sub) {
    case 0:
      return a.vendor_id;
    case 1:
      return a.product_code;
    case 2:
      return a.revision;
    default:
      return a.serial;
  }
}
}  // namespace

std::uint32_t LssAddress::part(int sub) const {
  return part_of(*this, sub);
}
std::uint32_t& LssAddress::part(int sub) {
  return part_of(*this, sub);
}

std::string to_string(const LssAddress& a) {
  char text[96];
  std::snprintf(text, sizeof text, "vendor %08Xh product %08Xh revision %08Xh serial %08Xh",
                a.vendor_id, a.product_code, a.revision, a.serial);
  return text;
}

std::string address_digits(const LssAddress& a, char separator) {
  std::string text;
  for (int sub = 0; sub < 4; ++sub) {
    if (sub != 0) text += separator;
    text += cfg::hex_digits(a.part(sub), 8);
  }
  return text;
}

std::string_view to_string(LssState state) {
  return state == LssState::Waiting ? "waiting" : "configuration";
}

namespace lss {

CanFrame make_frame(std::uint32_t cob_id, Cs cs, std::uint32_t value) {
  std::array<std::uint8_t, 8> bytes{};
  bytes[0] = static_cast<std::uint8_t>(cs);
  cfg::store_le(value, std::span(bytes).subspan(1), 4);
  return CanFrame::make(cob_id, bytes);
}

CanFrame make_frame(std::uint32_t cob_id, Cs cs, std::initializer_list<std::uint8_t> rest) {
  assert(rest.size() <= 7);
  std::array<std::uint8_t, 8> bytes{};
  bytes[0] = static_cast<std::uint8_t>(cs);
  std::size_t i = 1;
  for (auto b : rest) bytes[i++] = b;
  return CanFrame::make(cob_id, bytes);
}

CanFrame make_fastscan(std::uint32_t id_number, std::uint8_t bit_check, std::uint8_t lss_sub,
                       std::uint8_t lss_next) {
  auto frame = make_frame(kMasterCobId, Cs::Fastscan, id_number);
  frame.data[5] = bit_check;
  frame.data[6] = lss_sub;
  frame.data[7] = lss_next;
  return frame;
}

bool is_lss_frame(const CanFrame& frame, std::uint32_t cob_id) {
  return frame.id == cob_id && !frame.extended && !frame.rtr && !frame.error && frame.dlc == 8;
}

namespace {
// Table selector 0 (the CiA 301 table as CiA 305 indexes it); 0: no rate at that index.
constexpr std::array<std::uint16_t, 10> kBitRates{1000, 800, 500, 250, 125, 0, 50, 20, 10, 0};
}  // namespace

std::optional<std::uint16_t> bit_rate_kbit(std::uint8_t index) {
  if (index >= kBitRates.size() || kBitRates[index] == 0) return std::nullopt;
  return kBitRates[index];
}

std::optional<std::uint8_t> bit_timing_index(std::uint16_t kbit) {
  for (std::size_t i = 0; i < kBitRates.size(); ++i) {
    if (kbit != 0 && kBitRates[i] == kbit) return static_cast<std::uint8_t>(i);
  }
  return std::nullopt;
}

std::string error_text(Cs service, std::uint8_t error_code, std::uint8_t spec_error) {
  std::string what;
  if (error_code == 0) {
    what = "success";
  } else if (error_code == 0xFF) {
    char spec[48];
    std::snprintf(spec, sizeof spec, "manufacturer-specific error %02Xh", spec_error);
    what = spec;
  } else if (error_code == 1 && service == Cs::ConfigureNodeId) {
    what = "node-ID out of range";
  } else if (error_code == 1 && service == Cs::ConfigureBitTiming) {
    what = "bit rate not supported";
  } else if (error_code == 1 && service == Cs::StoreConfiguration) {
    what = "store configuration not supported";
  } else if (error_code == 2 && service == Cs::StoreConfiguration) {
    what = "storage media access error";
  } else {
    what = "reserved error code";
  }
  return what + " (error code " + std::to_string(error_code) + ")";
}

}  // namespace lss
}  // namespace nmt
