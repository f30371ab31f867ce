// cfgmgr: the CANopen configuration manager's command line. Each subcommand lives in its own
// file (commands.hpp); this file only builds the app and maps errors to exit codes.
#include <CLI/CLI.hpp>

#include <exception>
#include <iostream>
#include <string>

#include "../common/command_failure.hpp"
#include "../common/tool_support.hpp"
#include "commands.hpp"

namespace {

int run(int argc, char** argv) {
  CLI::App app{
      "CANopen configuration manager: check, format and compare device configurations, "
      "simulate devices, run the NMT master that boots and configures a network, build its "
      "master DCF and concise DCFs, and verify a configured network (CiA 302, CiA 306).",
      "cfgmgr"};
  app.require_subcommand(1);
  app.set_version_flag("--version", tools::version_text("cfgmgr"),
                       "Print the name and version and exit");
  app.footer(std::string("Run 'cfgmgr COMMAND --help' for a command's options and examples.\n\n") +
             std::string(tools::kExitCodesHelp));

  cfgmgr::add_check_command(app);
  cfgmgr::add_fmt_command(app);
  cfgmgr::add_simulate_command(app);
  cfgmgr::add_master_command(app);
  cfgmgr::add_push_command(app);
  cfgmgr::add_diff_command(app);
  cfgmgr::add_build_command(app);
  cfgmgr::add_verify_command(app);
  cfgmgr::add_store_command(app);
  cfgmgr::add_sdo_command(app);
  cfgmgr::add_lss_command(app);
  cfgmgr::add_scan_command(app);
  cfgmgr::add_program_image_command(app);

  try {
    app.parse(argc, argv);
  } catch (const tools::CommandFailure& failure) {
    return tools::finish_command(failure);  // a command ended early (tools::exit_with)
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? tools::kExitOk : tools::kExitUsage;
  }
  return tools::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    // Only resource exhaustion and the like end up here; bad input is a diagnostic.
    std::cerr << "cfgmgr: error: " << e.what() << '\n';
    return tools::kExitIo;
  } catch (...) {
    std::cerr << "cfgmgr: error: unexpected exception\n";
    return tools::kExitIo;
  }
}
