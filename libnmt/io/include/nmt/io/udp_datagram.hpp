// One CAN frame as a datagram of python-can's `udp_multicast` interface (python-can 4.1:
// can/interfaces/udp_multicast/utils.py), the codec of UdpBus (nmt/io/udp_bus.hpp). On its own so
// the parser of bytes any host on the group can send is tested and fuzzed without sockets.
//
// Wire format (python-can's pack_message): one MessagePack map per datagram with exactly the keys
// timestamp (float64, seconds since the Unix epoch), arbitration_id, is_extended_id,
// is_remote_frame, is_error_frame, channel (nil), dlc, data (bin), is_fd, bitrate_switch and
// error_state_indicator. python-can builds a can.Message(check=True) from the map, so one
// datagram with an unknown key or an inconsistent field stops its receive thread for good: we
// never send anything else.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "cfg/result.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

/// Encodes `frame` as one python-can datagram; `timestamp_s` is seconds since the Unix epoch.
/// Fails (without encoding) on a frame python-can would reject: id out of range for its format,
/// dlc > 8, or both `rtr` and `error` set.
cfg::Result<std::vector<std::uint8_t>> encode_udp_datagram(const CanFrame& frame,
                                                           double timestamp_s);
/// Decodes one datagram. Accepts what python-can itself accepts (missing keys take can.Message's
/// defaults, e.g. is_extended_id true) and ignores unknown keys. Fails with the reason on
/// anything else: not MessagePack, trailing bytes, a field of the wrong type or out of range,
/// CAN FD frames (not supported). Error frames come back with `extended` set, as SocketCanBus
/// reports them. The datagram's timestamp is ignored: the receiver stamps frames itself.
cfg::Result<CanFrame> decode_udp_datagram(std::span<const std::uint8_t> datagram);

}  // namespace nmt
