// SDO (CiA 301 §7.2.4) in one include: the frame codec (nmt/sdo/sdo_frame.hpp), the server
// (nmt/sdo/sdo_server.hpp) and the client with its multiplexer (nmt/sdo/sdo_client.hpp). All
// engines follow the contract of nmt/engine.hpp.
#pragma once

#include "nmt/sdo/sdo_client.hpp"
#include "nmt/sdo/sdo_frame.hpp"
#include "nmt/sdo/sdo_server.hpp"
