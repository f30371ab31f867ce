// SDO abort codes in libnmt: cfg::SdoAbort (cfg/sdo_abort.hpp, the one enum and the one table of
// texts of CiA 301 §7.2.4.3.17) under the name the SDO engines have always used.
#pragma once

#include "cfg/sdo_abort.hpp"

namespace nmt {

using cfg::describe;
using cfg::is_known;
using cfg::sdo_abort_table;
using cfg::SdoAbort;
using cfg::SdoAbortInfo;
using cfg::to_string;
using cfg::to_u32;
using cfg::operator<<;

}  // namespace nmt
