// Every public header of canopen::nmt_io: the real buses, the event loop, traces and
// sessions.
// Link canopen::nmt_io. A file that needs one part includes that header alone.
#pragma once

#include "nmt/io/bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/io/entry_persister.hpp"
#include "nmt/io/lss_session.hpp"
#include "nmt/io/remote_config_store.hpp"
#include "nmt/io/sdo_session.hpp"
#include "nmt/io/socketcan_bus.hpp"
#include "nmt/io/trace.hpp"
#include "nmt/io/udp_bus.hpp"
#include "nmt/io/udp_datagram.hpp"
