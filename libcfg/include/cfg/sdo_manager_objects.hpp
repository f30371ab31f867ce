// The words of the SDO manager's objects (DSP 302 §7.2.3) as value types: the one place of their
// bit layout, for the manager in the NMT master engine, the SDO requesting device (SRD) and the
// tools. Pure values: decode any 32/16-bit word, encode back to the same word; no I/O.
//   1F00h/1F01h  request / release SDO          SdoRequest
//   1F02h        SDO manager COB-IDs (the pool) ManagerCobId
//   1F03h-1F06h  SDO connections                SdoConnection
//   1F10h        dynamic SDO connection state   DynamicSdoState (on the SRD)
//   1F11h        slave failed                   SlaveFailed (on the SRD)
// and the Dynamic SDO Request frame (§7.2.1: COB-ID 1760, no data bytes).
#pragma once

#include <cstdint>
#include <string_view>

#include "cfg/cob_id.hpp"
#include "cfg/object_index.hpp"

namespace cfg::sdo_manager {

/// DSP 302 §7.2.1: the "Dynamic SDO Request" is a data frame without data bytes on COB-ID
/// 1760 (6E0h).
inline constexpr std::uint32_t kDynamicSdoRequestCanId = 1760;

/// DSP 302 §7.2.3: 1F03h-1F06h describe up to 254 connections each (sub 1..254).
inline constexpr unsigned kConnectionsPerPart = 254;
/// The four parts of the SDO connections table (1F03h mandatory, 1F04h-1F06h optional).
inline constexpr unsigned kConnectionParts = 4;

/// 1F00h Request SDO / 1F01h Release SDO (DSP 302 §7.2.3):
///   bits 31-16 index of the client SDO entry on the SRD (1280h-12FFh; 1F01h: 0 = all connections
///              to the slave), bits 15-8 SRD node-ID, bits 7-0 slave node-ID (1F01h: 0 = release
///              everything and de-register; 1F00h: must not be 0).
struct SdoRequest {
  std::uint16_t client_index = 0;
  std::uint8_t srd_node_id = 0;
  std::uint8_t slave_node_id = 0;

  static constexpr SdoRequest decode(std::uint32_t word) {
    return {static_cast<std::uint16_t>(word >> 16), static_cast<std::uint8_t>(word >> 8),
            static_cast<std::uint8_t>(word)};
  }
  constexpr std::uint32_t encode() const {
    return std::uint32_t{client_index} << 16 | std::uint32_t{srd_node_id} << 8 | slave_node_id;
  }
  /// 1F01h with index 0: every connection of the SRD to the slave.
  constexpr bool all_connections() const { return client_index == 0; }
  /// 1F01h with slave node-ID 0: release everything and de-register the SRD.
  constexpr bool deregister() const { return slave_node_id == 0; }
  constexpr bool operator==(const SdoRequest&) const = default;
};

/// 1F10h error code (DSP 302 §7.2.3), meaningful when the Cnxn state is 0 (failed).
enum class DynamicSdoError : std::uint8_t {
  kNoDetails = 0x00,               ///< no precise details for the reason of the error
  kNoChannelToManager = 0x01,      ///< no SDO channel free for connection from SRD to manager
  kNoFreeChannelInNetwork = 0x02,  ///< no more free SDO channels available in the network
  kNoFreeServerOnSlave = 0x03,     ///< no more free server SDO entries on slave S
  kSlaveNotAvailable = 0x04,       ///< slave S not available
};

/// The spec's description of an error code; "reserved error code" for 05h-FFh.
constexpr std::string_view describe(DynamicSdoError error) {
  switch (error) {
    case DynamicSdoError::kNoDetails:
      return "no precise details for the reason of the error";
    case DynamicSdoError::kNoChannelToManager:
      return "no SDO channel free for connection from SRD to SDO manager";
    case DynamicSdoError::kNoFreeChannelInNetwork:
      return "no more free SDO channels available in the network";
    case DynamicSdoError::kNoFreeServerOnSlave:
      return "no more free server SDO entries on slave S";
    case DynamicSdoError::kSlaveNotAvailable:
      return "slave S not available";
  }
  return "reserved error code";
}

/// 1F10h Cnxn state, bits 2-1 (DSP 302 §7.2.3).
enum class ConnectionState : std::uint8_t {
  kFailed = 0,               ///< no connection; the error code says why
  kManagerConnected = 1,     ///< SRD (client) <-> manager (server) established
  kAllDefaultSdosOwned = 2,  ///< the SRD owns all default SDOs (1F10h request 00000003h)
  kSlaveConnected = 3,       ///< the requested connection SRD -> slave S is established
};

/// 1F10h Dynamic SDO connection state, UNSIGNED32 on the SRD (DSP 302 §7.2.3):
///   bits 31-16 index of the client SDO entry (1280h-12FFh), bits 15-8 error code,
///   bits 7-4 reserved (0), bit 3 Req EC, bits 2-1 Cnxn state, bit 0 Rq indication.
/// decode() keeps the reserved bits (reserved_bits()) so a checker can report them; encode()
/// writes them as they were, so a decoded word round-trips.
struct DynamicSdoState {
  static constexpr std::uint32_t kRqIndication = 1U << 0;
  static constexpr std::uint32_t kCnxnStateMask = 0x3U << 1;
  static constexpr std::uint32_t kReqEc = 1U << 3;
  static constexpr std::uint32_t kReservedMask = 0xF0U;

  std::uint16_t client_index = 0;
  std::uint8_t error_code = 0;  ///< a DynamicSdoError when state == kFailed
  bool request_error_control = false;
  ConnectionState state = ConnectionState::kFailed;
  bool request_indication = false;
  std::uint8_t reserved = 0;  ///< bits 7-4 as read; 0 in every value the spec defines

  static constexpr DynamicSdoState decode(std::uint32_t word) {
    return {static_cast<std::uint16_t>(word >> 16),
            static_cast<std::uint8_t>(word >> 8),
            (word & kReqEc) != 0,
            static_cast<ConnectionState>((word & kCnxnStateMask) >> 1),
            (word & kRqIndication) != 0,
            static_cast<std::uint8_t>((word & kReservedMask) >> 4)};
  }
  constexpr std::uint32_t encode() const {
    return std::uint32_t{client_index} << 16 | std::uint32_t{error_code} << 8 |
           (std::uint32_t{reserved} << 4 & kReservedMask) | (request_error_control ? kReqEc : 0U) |
           (std::uint32_t{static_cast<std::uint8_t>(state)} << 1 & kCnxnStateMask) |
           (request_indication ? kRqIndication : 0U);
  }

  /// §7.2.3: the SRD's registration request xxxx0001h, or xxxx0009h with error control of
  /// the slaves it connects to; `client_index` is the free client entry for the channel to the
  /// manager.
  static constexpr DynamicSdoState registration(std::uint16_t client_index,
                                                bool request_error_control = false) {
    DynamicSdoState s;
    s.client_index = client_index;
    s.request_error_control = request_error_control;
    s.request_indication = true;
    return s;
  }
  /// §7.2.3: the request for all default SDOs, 00000003h (Cnxn state field 1, Rq indication).
  static constexpr DynamicSdoState all_default_sdos_request() {
    DynamicSdoState s;
    s.state = ConnectionState::kManagerConnected;
    s.request_indication = true;
    return s;
  }
  /// The manager's confirmation: Rq indication reset, the state set.
  static constexpr DynamicSdoState confirmation(std::uint16_t client_index, ConnectionState state,
                                                bool request_error_control = false) {
    DynamicSdoState s;
    s.client_index = client_index;
    s.state = state;
    s.request_error_control = request_error_control;
    return s;
  }
  /// The manager's report of a failure (Cnxn state 0) with its reason.
  static constexpr DynamicSdoState failure(std::uint16_t client_index, DynamicSdoError error) {
    DynamicSdoState s;
    s.client_index = client_index;
    s.error_code = static_cast<std::uint8_t>(error);
    return s;
  }

  constexpr bool is_all_default_sdos_request() const {
    return encode() == all_default_sdos_request().encode();
  }
  constexpr DynamicSdoError error() const { return static_cast<DynamicSdoError>(error_code); }
  constexpr bool operator==(const DynamicSdoState&) const = default;
};

/// 1F11h Slave failed reason (DSP 302 §7.2.3).
enum class SlaveFailedReason : std::uint8_t {
  kErrorControl = 0x00,  ///< slave S failed to respond on node guard / heartbeat protocol
};

/// 1F11h Slave failed, UNSIGNED16 on the SRD (DSP 302 §7.2.3): bits 15-8 reason, 7-0 slave
/// node-ID.
struct SlaveFailed {
  std::uint8_t reason = 0;  ///< a SlaveFailedReason; 01h-FFh reserved
  std::uint8_t slave_node_id = 0;

  static constexpr SlaveFailed decode(std::uint16_t word) {
    return {static_cast<std::uint8_t>(word >> 8), static_cast<std::uint8_t>(word)};
  }
  constexpr std::uint16_t encode() const {
    return static_cast<std::uint16_t>(std::uint16_t{reason} << 8 | slave_node_id);
  }
  constexpr bool operator==(const SlaveFailed&) const = default;
};

/// The description of a 1F11h reason; "reserved reason" for 01h-FFh.
constexpr std::string_view describe(SlaveFailedReason reason) {
  return reason == SlaveFailedReason::kErrorControl
             ? "slave failed to respond on node guarding / heartbeat protocol"
             : "reserved reason";
}

/// One entry (sub 1..n) of 1F02h SDO manager COB-IDs (DSP 302 §7.2.3): bit 31 1 = not valid
/// (entry not configured), bit 30 1 = in use by a connection, bit 29 29-bit identifier, the
/// identifier in bits 0-28 (bits 0-10 when 11-bit). The identifier part is a cfg::CobId.
struct ManagerCobId {
  std::uint32_t word = kCobIdInvalidBit;  ///< not configured

  static constexpr ManagerCobId decode(std::uint32_t value) { return {value}; }
  constexpr std::uint32_t encode() const { return word; }

  /// An unused, valid pool entry for `can_id`.
  static constexpr ManagerCobId of(CanId can_id) { return {CobId::of(can_id).word()}; }
  constexpr bool valid() const { return (word & kCobIdInvalidBit) == 0; }
  constexpr bool in_use() const { return (word & kCobIdBit30) != 0; }
  /// Configured and not in use: the manager may allocate it.
  constexpr bool free() const { return valid() && !in_use(); }
  /// The COB-ID a connection puts into a 1200h/1280h entry: bit 31 and bit 30 clear.
  constexpr CobId cob_id() const {
    return CobId::from_word(word & ~(kCobIdInvalidBit | kCobIdBit30));
  }
  constexpr ManagerCobId with_in_use(bool in_use) const {
    return {in_use ? (word | kCobIdBit30) : (word & ~kCobIdBit30)};
  }
  constexpr bool operator==(const ManagerCobId&) const = default;
};

/// One entry of 1F03h-1F06h SDO connections (DSP 302 §7.2.3): bits 31-24 client offset (from
/// 1280h), 23-16 client node-ID, 15-8 server offset (from 1200h), 7-0 server (slave) node-ID.
/// Free when either node-ID is 0.
struct SdoConnection {
  std::uint8_t client_offset = 0;
  std::uint8_t client_node_id = 0;
  std::uint8_t server_offset = 0;
  std::uint8_t server_node_id = 0;

  static constexpr SdoConnection decode(std::uint32_t word) {
    return {static_cast<std::uint8_t>(word >> 24), static_cast<std::uint8_t>(word >> 16),
            static_cast<std::uint8_t>(word >> 8), static_cast<std::uint8_t>(word)};
  }
  constexpr std::uint32_t encode() const {
    return std::uint32_t{client_offset} << 24 | std::uint32_t{client_node_id} << 16 |
           std::uint32_t{server_offset} << 8 | server_node_id;
  }
  constexpr bool free() const { return client_node_id == 0 || server_node_id == 0; }
  /// The client's 1280h+ index and the server's 1200h+ index of the connection.
  constexpr std::uint16_t client_index() const {
    return static_cast<std::uint16_t>(object::kSdoClientFirst + client_offset);
  }
  constexpr std::uint16_t server_index() const {
    return static_cast<std::uint16_t>(object::kSdoServerFirst + server_offset);
  }
  /// A connection from the client entry `client_index` (1280h-12FFh) on `client_node_id` to
  /// the server entry `server_index` (1200h-127Fh) on `server_node_id`.
  static constexpr SdoConnection of(std::uint16_t client_index, std::uint8_t client_node_id,
                                    std::uint16_t server_index, std::uint8_t server_node_id) {
    return {static_cast<std::uint8_t>(client_index - object::kSdoClientFirst), client_node_id,
            static_cast<std::uint8_t>(server_index - object::kSdoServerFirst), server_node_id};
  }
  constexpr bool operator==(const SdoConnection&) const = default;
};

/// The 1F03h-1F06h index and sub-index of connection number `n` (0-based, < 4 * 254).
struct ConnectionSlot {
  std::uint16_t index = 0;
  std::uint8_t sub_index = 0;
  constexpr bool operator==(const ConnectionSlot&) const = default;
};
constexpr ConnectionSlot connection_slot(unsigned n) {
  return {static_cast<std::uint16_t>(object::kSdoConnectionsFirst + n / kConnectionsPerPart),
          static_cast<std::uint8_t>(1 + n % kConnectionsPerPart)};
}

}  // namespace cfg::sdo_manager
