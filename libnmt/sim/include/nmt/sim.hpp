// Every public header of canopen::nmt_sim: the simulated bus and devices.
// Link canopen::nmt_sim. A file that needs one part includes that header alone.
#pragma once

#include "nmt/sim/device_state.hpp"
#include "nmt/sim/fault_injection.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/sim_network.hpp"
#include "nmt/sim/simulated_device.hpp"
