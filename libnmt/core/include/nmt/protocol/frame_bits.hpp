// The length of a classic CAN frame on the wire, in bits (ISO 11898-1): the simulated bus times
// frames with it, the NMT master paces its boot with it (MasterOptions::pacing.bitrate).
#pragma once

#include <cstdint>
#include <span>

#include "nmt/protocol/frame.hpp"

namespace nmt {

/// The length of a classic CAN frame on the wire, in bits (ISO 11898-1).
struct FrameBits {
  unsigned stuffed_region = 0;  ///< SOF .. end of CRC sequence: the bits stuffing applies to
  unsigned stuff_bits = 0;      ///< bits inserted after 5 equal bits (counted on the real bits)
  unsigned trailer = 10;        ///< CRC delimiter 1, ACK slot 1, ACK delimiter 1, EOF 7
  unsigned intermission = 3;    ///< interframe space before the bus is free
  /// SOF to end of EOF: the bits before a receiver accepts the frame.
  unsigned until_eof() const { return stuffed_region + stuff_bits + trailer; }
  unsigned total() const { return until_eof() + intermission; }
};

/// The number of stuff bits ISO 11898-1 (bit stuffing) inserts into `bits` (one bit per element, 0
/// or 1): after five equal bits a complementary bit, which itself starts the next run.
unsigned count_stuff_bits(std::span<const std::uint8_t> bits);

/// CAN CRC-15 (generator 0x4599, initial 0) over `bits` (one bit per element).
std::uint16_t can_crc15(std::span<const std::uint8_t> bits);

/// Computes the exact bit length of a data or remote frame: the real bit sequence SOF,
/// arbitration, control, data, CRC-15 is built and stuffed. Error frames (frame.error) are
/// given the length of an active error flag plus delimiter: 6 + 8 bits + intermission.
FrameBits frame_bits(const CanFrame& frame);

}  // namespace nmt
