// Object indices of CiA 301 and CiA 302 that code refers to by name: named once here, so that a
// reader finds "kVerifyConfiguration" rather than 0x1020 in protocol code. Ranges of repeated
// objects (SDO channels, PDOs) with their membership tests.
#pragma once

#include <cstdint>
#include <optional>

namespace cfg::object {

// CiA 301 communication profile area.
inline constexpr std::uint16_t kDeviceType = 0x1000;
inline constexpr std::uint16_t kErrorRegister = 0x1001;
inline constexpr std::uint16_t kPreDefinedErrorField = 0x1003;
inline constexpr std::uint16_t kCobIdSync = 0x1005;
inline constexpr std::uint16_t kGuardTime = 0x100C;
inline constexpr std::uint16_t kLifeTimeFactor = 0x100D;
inline constexpr std::uint16_t kStoreParameters = 0x1010;
inline constexpr std::uint16_t kRestoreDefaultParameters = 0x1011;
inline constexpr std::uint16_t kCobIdTime = 0x1012;
inline constexpr std::uint16_t kCobIdEmcy = 0x1014;
inline constexpr std::uint16_t kInhibitTimeEmcy = 0x1015;
inline constexpr std::uint16_t kConsumerHeartbeatTime = 0x1016;
inline constexpr std::uint16_t kProducerHeartbeatTime = 0x1017;
inline constexpr std::uint16_t kIdentity =
    0x1018;  ///< sub 1 vendor, 2 product, 3 revision, 4 serial
inline constexpr std::uint16_t kVerifyConfiguration = 0x1020;  ///< sub 1 date, sub 2 time
inline constexpr std::uint16_t kErrorBehaviour = 0x1029;
inline constexpr std::uint16_t kNmtInhibitTime = 0x102A;

// Repeated communication objects (CiA 301 §7.5.2.33-38).
inline constexpr std::uint16_t kSdoServerFirst = 0x1200;
inline constexpr std::uint16_t kSdoServerLast = 0x127F;
inline constexpr std::uint16_t kSdoClientFirst = 0x1280;
inline constexpr std::uint16_t kSdoClientLast = 0x12FF;
inline constexpr std::uint16_t kRpdoCommunicationFirst = 0x1400;
inline constexpr std::uint16_t kRpdoMappingFirst = 0x1600;
inline constexpr std::uint16_t kTpdoCommunicationFirst = 0x1800;
inline constexpr std::uint16_t kTpdoMappingFirst = 0x1A00;
inline constexpr std::uint16_t kPdoCount = 0x200;  ///< PDOs per direction (512)

// CiA 302 (DSP 302) manager objects.
inline constexpr std::uint16_t kSdoRequest = 0x1F00;
inline constexpr std::uint16_t kSdoRelease = 0x1F01;
inline constexpr std::uint16_t kSdoManagerCobIds = 0x1F02;           ///< the manager's COB-ID pool
inline constexpr std::uint16_t kSdoConnectionsFirst = 0x1F03;        ///< part 1 (mandatory)
inline constexpr std::uint16_t kSdoConnectionsLast = 0x1F06;         ///< part 4
inline constexpr std::uint16_t kDynamicSdoConnectionState = 0x1F10;  ///< on the SRD
inline constexpr std::uint16_t kSlaveFailed = 0x1F11;                ///< on the SRD
inline constexpr std::uint16_t kStoreDcf = 0x1F20;
inline constexpr std::uint16_t kStorageFormat = 0x1F21;
inline constexpr std::uint16_t kConciseDcf = 0x1F22;
inline constexpr std::uint16_t kStoreEds = 0x1F23;
inline constexpr std::uint16_t kStorageFormatEds = 0x1F24;
inline constexpr std::uint16_t kConfigureSlave = 0x1F25;
inline constexpr std::uint16_t kExpectedConfigurationDate = 0x1F26;
inline constexpr std::uint16_t kExpectedConfigurationTime = 0x1F27;
inline constexpr std::uint16_t kProgramData = 0x1F50;
inline constexpr std::uint16_t kProgramControl = 0x1F51;
inline constexpr std::uint16_t kVerifyApplicationSoftware = 0x1F52;
inline constexpr std::uint16_t kExpectedApplicationSwDate = 0x1F53;
inline constexpr std::uint16_t kExpectedApplicationSwTime = 0x1F54;
/// CiA 302-3, master: the software identification expected of node N (sub N), compared with
/// the slave's 1F56h sub 1 (lely-core's master and dcfgen's `software_version`).
inline constexpr std::uint16_t kExpectedSoftwareIdentification = 0x1F55;
inline constexpr std::uint16_t kProgramSoftwareIdentification = 0x1F56;
inline constexpr std::uint16_t kFlashStatusIdentification = 0x1F57;
/// CiA 302-3, master: the program image for node N (sub N, DOMAIN; dcfgen's `software_file`).
inline constexpr std::uint16_t kSlaveProgramData = 0x1F58;
inline constexpr std::uint16_t kDynamicChannelsProcessPicture = 0x1F70;
inline constexpr std::uint16_t kNmtStartup = 0x1F80;
inline constexpr std::uint16_t kSlaveAssignment = 0x1F81;
inline constexpr std::uint16_t kRequestNmt = 0x1F82;
inline constexpr std::uint16_t kRequestGuarding = 0x1F83;
inline constexpr std::uint16_t kDeviceTypeIdentification = 0x1F84;
inline constexpr std::uint16_t kVendorIdentification = 0x1F85;
inline constexpr std::uint16_t kProductCode = 0x1F86;
inline constexpr std::uint16_t kRevisionNumber = 0x1F87;
inline constexpr std::uint16_t kSerialNumber = 0x1F88;
inline constexpr std::uint16_t kBootTime = 0x1F89;
inline constexpr std::uint16_t kRestoreConfiguration = 0x1F8A;
inline constexpr std::uint16_t kFlyingMasterParameters = 0x1F90;
inline constexpr std::uint16_t kSelfStartingNodesTiming = 0x1F91;

// Areas of the dictionary (CiA 301 §7.4.1, Table 42).
inline constexpr std::uint16_t kCommunicationAreaFirst = 0x1000;
inline constexpr std::uint16_t kCommunicationAreaLast = 0x1FFF;
inline constexpr std::uint16_t kManufacturerAreaFirst = 0x2000;
inline constexpr std::uint16_t kManufacturerAreaLast = 0x5FFF;
inline constexpr std::uint16_t kProfileAreaFirst = 0x6000;
inline constexpr std::uint16_t kProfileAreaLast = 0x9FFF;

constexpr bool is_sdo_server_parameter(std::uint16_t index) {
  return index >= kSdoServerFirst && index <= kSdoServerLast;
}
constexpr bool is_sdo_client_parameter(std::uint16_t index) {
  return index >= kSdoClientFirst && index <= kSdoClientLast;
}
/// 1F03h-1F06h SDO connections (DSP 302 §7.2.3).
constexpr bool is_sdo_connections(std::uint16_t index) {
  return index >= kSdoConnectionsFirst && index <= kSdoConnectionsLast;
}

/// PDO parameter indices (CiA 301 §7.5.2.35-38): the communication and mapping index of the
/// PDO an index belongs to.
struct PdoIndices {
  std::uint16_t comm_index = 0;     ///< 1400h-15FFh (RPDO) or 1800h-19FFh (TPDO)
  std::uint16_t mapping_index = 0;  ///< 1600h-17FFh (RPDO) or 1A00h-1BFFh (TPDO)
  bool receive = false;             ///< an RPDO
  constexpr bool operator==(const PdoIndices&) const = default;
};
/// nullopt for an index that is no PDO parameter.
constexpr std::optional<PdoIndices> pdo_indices_of(std::uint16_t index) {
  for (const std::uint16_t comm : {kRpdoCommunicationFirst, kTpdoCommunicationFirst}) {
    const std::uint16_t mapping = static_cast<std::uint16_t>(comm + kPdoCount);
    const bool receive = comm == kRpdoCommunicationFirst;
    if (index >= comm && index < comm + kPdoCount) {
      return PdoIndices{index, static_cast<std::uint16_t>(index + kPdoCount), receive};
    }
    if (index >= mapping && index < mapping + kPdoCount) {
      return PdoIndices{static_cast<std::uint16_t>(index - kPdoCount), index, receive};
    }
  }
  return std::nullopt;
}
constexpr bool is_pdo_communication(std::uint16_t index) {
  const auto p = pdo_indices_of(index);
  return p && p->comm_index == index;
}
constexpr bool is_pdo_mapping(std::uint16_t index) {
  const auto p = pdo_indices_of(index);
  return p && p->mapping_index == index;
}

}  // namespace cfg::object
