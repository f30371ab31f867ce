// The length of a classic CAN frame on the wire (ISO 11898-1): used by the simulated bus to
// time frames and by the master to pace its boot (docs/master.md, MasterOptions::pacing.bitrate).
#include "nmt/protocol/frame_bits.hpp"

#include <algorithm>
#include <array>

namespace nmt {

namespace {

// The simulated bus computes the length of every frame it carries, so this is its hot path: the
// frame is packed into bytes and CRC and stuffing advance a byte at a time through tables. The
// bit-at-a-time can_crc15() and count_stuff_bits() below define the results; the tests compare
// the two.

// CRC-15 register after shifting in the byte `i` (aligned with the register's top bits).
constexpr std::array<std::uint16_t, 256> make_crc15_table() {
  std::array<std::uint16_t, 256> table{};
  for (unsigned i = 0; i < 256; ++i) {
    auto crc = static_cast<std::uint16_t>(i << 7);
    for (int bit = 0; bit < 8; ++bit) {
      crc = static_cast<std::uint16_t>((crc & 0x4000) != 0 ? ((crc << 1) ^ 0x4599) & 0x7FFF
                                                           : (crc << 1) & 0x7FFF);
    }
    table[i] = crc;
  }
  return table;
}
constexpr auto kCrc15Table = make_crc15_table();

// Stuffing as a state machine over runs: state 0 = no bit yet, 1 + previous * 4 + (run - 1)
// for a run of 1..4 equal bits (a run of 5 is cut by a stuff bit at once).
struct StuffStep {
  std::uint8_t next;
  std::uint8_t stuffed;
};
constexpr StuffStep stuff_bit(std::uint8_t state, unsigned bit) {
  int previous = state == 0 ? -1 : (state - 1) / 4;
  unsigned run = state == 0 ? 0 : (state - 1) % 4 + 1;
  std::uint8_t stuffed = 0;
  if (static_cast<int>(bit) == previous) {
    ++run;
  } else {
    previous = static_cast<int>(bit);
    run = 1;
  }
  if (run == 5) {
    stuffed = 1;
    previous = 1 - previous;
    run = 1;
  }
  return {static_cast<std::uint8_t>(1 + previous * 4 + static_cast<int>(run) - 1), stuffed};
}
constexpr std::array<std::array<StuffStep, 256>, 9> make_stuff_table() {
  std::array<std::array<StuffStep, 256>, 9> table{};
  for (std::uint8_t state = 0; state < 9; ++state) {
    for (unsigned byte = 0; byte < 256; ++byte) {
      StuffStep acc{state, 0};
      for (int i = 7; i >= 0; --i) {
        auto step = stuff_bit(acc.next, byte >> i & 1U);
        acc = {step.next, static_cast<std::uint8_t>(acc.stuffed + step.stuffed)};
      }
      table[state][byte] = acc;
    }
  }
  return table;
}
constexpr auto kStuffTable = make_stuff_table();

// The bits of a frame from SOF to the end of the CRC sequence, fed MSB first.
class FrameBitStream {
 public:
  void put(std::uint32_t value, unsigned width) {  // width <= 24
    acc_ = acc_ << width | (value & ((1U << width) - 1));
    pending_ += width;
    total_ += width;
    while (pending_ >= 8) {
      pending_ -= 8;
      consume(static_cast<std::uint8_t>(acc_ >> pending_));
    }
  }
  // Ends the bits the CRC covers and returns the CRC of them.
  std::uint16_t finish_crc() {
    for (unsigned i = pending_; i-- > 0;) {
      const bool next = (acc_ >> i & 1U) != ((crc_ >> 14 & 1U) != 0);
      crc_ = static_cast<std::uint16_t>(crc_ << 1 & 0x7FFF);
      if (next) crc_ ^= 0x4599;
    }
    crc_done_ = true;
    return crc_;
  }
  // Stuff bits of everything put so far.
  unsigned finish_stuffing() {
    for (unsigned i = pending_; i-- > 0;) {
      const auto step = stuff_bit(stuff_state_, acc_ >> i & 1U);
      stuff_state_ = step.next;
      stuffed_ += step.stuffed;
    }
    pending_ = 0;
    return stuffed_;
  }
  unsigned size() const { return total_; }

 private:
  void consume(std::uint8_t byte) {
    if (!crc_done_) {
      crc_ = static_cast<std::uint16_t>(((crc_ << 8) & 0x7FFF) ^
                                        kCrc15Table[((crc_ >> 7) ^ byte) & 0xFF]);
    }
    const auto step = kStuffTable[stuff_state_][byte];
    stuff_state_ = step.next;
    stuffed_ += step.stuffed;
  }

  std::uint64_t acc_ = 0;
  unsigned pending_ = 0;  // low bits of acc_ not consumed yet (< 8 between calls)
  unsigned total_ = 0;
  std::uint16_t crc_ = 0;
  bool crc_done_ = false;
  std::uint8_t stuff_state_ = 0;
  unsigned stuffed_ = 0;
};

}  // namespace

// ISO 11898-1, CRC field: CRC-15, generator x^15+x^14+x^10+x^8+x^7+x^4+x^3+1 (0x4599), over SOF,
// arbitration, control and data fields.
std::uint16_t can_crc15(std::span<const std::uint8_t> bits) {
  std::uint16_t crc = 0;
  for (auto bit : bits) {
    const bool next = (bit != 0) != ((crc >> 14 & 1U) != 0);
    crc = static_cast<std::uint16_t>(crc << 1 & 0x7FFF);
    if (next) crc ^= 0x4599;
  }
  return crc;
}

unsigned count_stuff_bits(std::span<const std::uint8_t> bits) {
  unsigned stuffed = 0;
  unsigned run = 0;
  int previous = -1;
  for (auto b : bits) {
    const int bit = b != 0 ? 1 : 0;
    if (bit == previous) {
      ++run;
    } else {
      previous = bit;
      run = 1;
    }
    if (run == 5) {
      ++stuffed;
      previous = 1 - bit;  // the stuff bit starts the next run
      run = 1;
    }
  }
  return stuffed;
}

FrameBits frame_bits(const CanFrame& frame) {
  FrameBits bits;
  if (frame.error) {
    // Active error flag (6 dominant bits) and error delimiter (8 recessive bits).
    bits.stuffed_region = 14;
    bits.trailer = 0;
    return bits;
  }
  const unsigned dlc = std::min<unsigned>(frame.dlc, 8);
  const unsigned data_bytes = frame.rtr ? 0 : dlc;
  FrameBitStream w;
  w.put(0, 1);  // SOF
  if (frame.extended) {
    w.put(frame.id >> 18 & 0x7FF, 11);  // base identifier
    w.put(1, 1);                        // SRR (recessive)
    w.put(1, 1);                        // IDE (recessive: extended)
    w.put(frame.id & 0x3FFFF, 18);      // identifier extension
    w.put(frame.rtr ? 1 : 0, 1);        // RTR
    w.put(0, 2);                        // r1, r0
  } else {
    w.put(frame.id & 0x7FF, 11);
    w.put(frame.rtr ? 1 : 0, 1);  // RTR
    w.put(0, 1);                  // IDE (dominant: standard)
    w.put(0, 1);                  // r0
  }
  w.put(dlc, 4);
  for (unsigned i = 0; i < data_bytes; ++i) w.put(frame.data[i], 8);
  w.put(w.finish_crc(), 15);
  bits.stuffed_region = w.size();
  bits.stuff_bits = w.finish_stuffing();
  return bits;
}

}  // namespace nmt
