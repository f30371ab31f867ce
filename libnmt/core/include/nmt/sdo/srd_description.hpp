// The device description of the SDO requesting device an SdoSession becomes to ask the SDO
// manager for a channel (nmt/io/sdo_session.hpp, DSP 302 §7.2.3): sans-I/O data, kept in core.
#pragma once

#include <string_view>

namespace nmt {

/// An EDS with what an SDO requesting device needs: 1000h, 1001h, 1017h (heartbeat 200 ms),
/// 1018h, 1F10h, 1F11h and two SDO client entries (1280h to the manager, 1281h for the
/// connection).
std::string_view session_srd_description();

}  // namespace nmt
