// The values of the NMT master's objects and the signatures of the storage objects, as bits
// and numbers: the one place of their layout, for the master engine (libnmt), the network
// description and the tools that build master DCFs.
//   1F80h NMT startup             CiA 302-2 §6.2, Tables 8-16
//   1F81h NMT slave assignment    CiA 302-2 §6.3, Tables 19-25 (byte 1 retry factor, bytes 2-3
//                                 guard time in ms)
//   1010h/1011h 'save'/'load', 1F25h 'conf' signatures (CiA 301 §7.5.2.13-14, DSP 302 §6)
//   the date and time of 1020h, 1F26h/1F27h and 1F52h-1F54h: days since 1 January 1984 and
//   milliseconds after midnight (DSP 302 §6.3, §9)
#pragma once

#include <cstdint>

namespace cfg {

/// 1F80h NMT startup (CiA 302-2 §6.2).
struct NmtStartup {
  static constexpr std::uint32_t kMaster = 1U << 0;             ///< Table 8: device is NMT master
  static constexpr std::uint32_t kStartAllNodes = 1U << 1;      ///< Table 9: start with node-ID 0
  static constexpr std::uint32_t kNoAutoOperational = 1U << 2;  ///< Table 10: master stays pre-op
  static constexpr std::uint32_t kNoStartSlaves = 1U << 3;      ///< Table 11: app starts slaves
  static constexpr std::uint32_t kResetAllNodes = 1U << 4;      ///< Table 12: on mandatory error
  static constexpr std::uint32_t kFlyingMaster = 1U << 5;       ///< Table 13: flying master
  static constexpr std::uint32_t kStopAllNodes = 1U << 6;       ///< Table 14: on mandatory error
  /// Bits 7-31 are reserved (DSP 302 §5.1).
  static constexpr std::uint32_t kDefinedBits = 0x7F;

  std::uint32_t value = 0;

  constexpr bool is_master() const { return (value & kMaster) != 0; }
  constexpr bool start_all_nodes() const { return (value & kStartAllNodes) != 0; }
  constexpr bool no_auto_operational() const { return (value & kNoAutoOperational) != 0; }
  constexpr bool no_start_slaves() const { return (value & kNoStartSlaves) != 0; }
  constexpr bool reset_all_nodes() const { return (value & kResetAllNodes) != 0; }
  constexpr bool flying_master() const { return (value & kFlyingMaster) != 0; }
  constexpr bool stop_all_nodes() const { return (value & kStopAllNodes) != 0; }
  /// Table 16: a start-up capable device that is no master but enters operational by itself
  /// (0000 1000b), or that also starts all nodes (0000 0010b).
  constexpr bool self_starting() const {
    return !is_master() && (value & (kNoStartSlaves | kStartAllNodes)) != 0 &&
           !no_auto_operational();
  }
};

/// One sub-index of 1F81h NMT slave assignment (CiA 302-2 §6.3).
struct SlaveAssignment {
  static constexpr std::uint32_t kSlave = 1U << 0;           ///< Table 19: slave in the network
  static constexpr std::uint32_t kReservedBit1 = 1U << 1;    ///< DSP 302: reserved
  static constexpr std::uint32_t kBootSlave = 1U << 2;       ///< Table 20: configure and start
  static constexpr std::uint32_t kMandatory = 1U << 3;       ///< Table 21
  static constexpr std::uint32_t kKeepAlive = 1U << 4;       ///< Table 22: no reset comm when op
  static constexpr std::uint32_t kVerifySoftware = 1U << 5;  ///< Table 23
  static constexpr std::uint32_t kUpdateSoftware = 1U << 6;  ///< Table 24
  static constexpr std::uint32_t kRestore = 1U << 7;         ///< Table 25: restore (1011h) first

  std::uint32_t value = 0;

  constexpr bool is_slave() const { return (value & kSlave) != 0; }
  constexpr bool boot_slave() const { return (value & kBootSlave) != 0; }
  constexpr bool mandatory() const { return (value & kMandatory) != 0; }
  constexpr bool keep_alive() const { return (value & kKeepAlive) != 0; }
  constexpr bool verify_software() const { return (value & kVerifySoftware) != 0; }
  constexpr bool update_software() const { return (value & kUpdateSoftware) != 0; }
  constexpr bool restore() const { return (value & kRestore) != 0; }
  /// Byte 1: node guarding retries (CiA 302-2 §6.3; 0 disables guarding).
  constexpr std::uint8_t retry_factor() const { return static_cast<std::uint8_t>(value >> 8); }
  /// Bytes 2-3: guard time in ms (0 disables guarding).
  constexpr std::uint16_t guard_time_ms() const { return static_cast<std::uint16_t>(value >> 16); }

  /// A value from its parts: `flags` are the bits above (byte 0).
  static constexpr SlaveAssignment make(std::uint8_t flags, std::uint8_t retry_factor = 0,
                                        std::uint16_t guard_time_ms = 0) {
    return {std::uint32_t{flags} | std::uint32_t{retry_factor} << 8 |
            std::uint32_t{guard_time_ms} << 16};
  }
};

/// 1010h sub n: "save" written as UNSIGNED32 (CiA 301 §7.5.2.13).
inline constexpr std::uint32_t kSaveSignature = 0x65766173;
/// 1011h sub n: "load" (CiA 301 §7.5.2.14).
inline constexpr std::uint32_t kLoadSignature = 0x64616F6C;
/// 1F25h sub n: "conf" starts the configuration of a slave (DSP 302 §6.4).
inline constexpr std::uint32_t kConfigureSignature = 0x666E6F63;

/// A date and time as 1020h sub 1/2, 1F26h/1F27h and 1F52h-1F54h hold them.
struct ConfigurationStamp {
  std::uint32_t days = 0;  ///< days since 1 January 1984
  std::uint32_t ms = 0;    ///< milliseconds after midnight, < 86 400 000
  constexpr bool operator==(const ConfigurationStamp&) const = default;
  /// 1F26h/1F27h of 0 mean "do not verify" (CiA 302-2 §3.5 a).
  constexpr bool is_zero() const { return days == 0 && ms == 0; }
};

}  // namespace cfg
