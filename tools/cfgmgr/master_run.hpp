// What the cfgmgr commands that run a network (master, push, verify) share, one header per
// concern: their arguments (run_args.hpp), the network loaded and its master built
// (network_load.hpp), the master's events printed (event_reporter.hpp), and the run on the
// simulated or a real bus (master_runners.hpp). Each command adds its own options and, for push,
// the report at the end.
#pragma once

#include "event_reporter.hpp"
#include "master_runners.hpp"
#include "network_load.hpp"
#include "run_args.hpp"
