// cfgmgr subcommands: each lives in its own file and registers itself on the app with one
// add_<name>_command call in main.cpp. A command's callback does its work and, when the exit
// code is not 0, ends with exit_with(code) or fail_command(TOOL, code, message) (one way to end a
// command: ../common/command_failure.hpp); main prints the message and returns that code.
#pragma once

#include <CLI/CLI.hpp>

#include "../common/command_failure.hpp"

namespace cfgmgr {

/// `cfgmgr check FILE...`: read EDS/DCF files, print every diagnostic (check.cpp).
void add_check_command(CLI::App& app);
/// `cfgmgr fmt IN [-o OUT]`: write a device file back in canonical form (fmt.cpp).
void add_fmt_command(CLI::App& app);
/// `cfgmgr simulate DEVICE.eds[@ID]...`: run simulated slaves on a bus (simulate.cpp).
void add_simulate_command(CLI::App& app);
/// `cfgmgr master NETWORK --bus URL`: run the CiA 302-2 NMT master for a network (master.cpp).
void add_master_command(CLI::App& app);
/// `cfgmgr push NETWORK --bus URL`: boot and configure a network, then report (push.cpp).
void add_push_command(CLI::App& app);
/// `cfgmgr diff A.dcf B.dcf`: the parameters two device files configure differently (diff.cpp).
void add_diff_command(CLI::App& app);
/// `cfgmgr build NETWORK -o DIR`: the master DCF and every node's concise DCF (build.cpp).
void add_build_command(CLI::App& app);
/// `cfgmgr verify NETWORK --bus URL`: read back the configured values and compare (verify.cpp).
void add_verify_command(CLI::App& app);
/// `cfgmgr store put|get|list|rm|configure`: a configuration store, local or a master's
/// (store.cpp).
void add_store_command(CLI::App& app);
/// `cfgmgr sdo read|write --bus URL NODE INDEX[:SUB] [VALUE]`: one SDO transfer (sdo.cpp).
void add_sdo_command(CLI::App& app);
/// `cfgmgr lss scan|set-id|inquire|set-bitrate --bus URL`: LSS, CiA 305 (lss.cpp).
void add_lss_command(CLI::App& app);
/// `cfgmgr scan --bus URL --eds-dir DIR -o OUT`: a live network into a project (scan.cpp).
void add_scan_command(CLI::App& app);
/// `cfgmgr program-image PAYLOAD --version V -o IMAGE`: an image with a version trailer
/// (program_image.cpp).
void add_program_image_command(CLI::App& app);

}  // namespace cfgmgr
