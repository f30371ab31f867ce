// cfgmgr program-image PAYLOAD --version VERSION -o IMAGE: an application program image with
// our version trailer (cfg/program_image.hpp; DSP 302 §9 leaves the image format to the
// manufacturer), the image a simulated device reports the version of in 1F52h once started.
// Without --version it prints the version an image's trailer carries.
#include <iostream>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "../common/tool_support.hpp"
#include "cfg/program_image.hpp"
#include "commands.hpp"

namespace cfgmgr {
namespace {

struct ProgramImageOptions {
  std::string input;
  std::string version;
  std::string output;
};

void run_program_image(const ProgramImageOptions& options) {
  auto input = tools::read_input(options.input);
  if (!input) {
    exit_with(tools::exit_code_for(input.error()), input.error().message);
  }
  const std::string_view text = input->view();
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(text.data()),
                                            text.size());
  if (options.version.empty()) {
    // Inspect: the trailer's version, or say there is none (exit 1: nothing to report).
    const auto version = cfg::program_image_version(bytes);
    if (!version) {
      exit_with(tools::kExitInputErrors, options.input + ": error: no version trailer (the last " +
                                             std::to_string(cfg::kProgramTrailerSize) +
                                             " bytes do not end in \"" +
                                             std::string(cfg::kProgramTrailerMagic) + "\")");
    }
    std::cout << options.input << ": " << tools::plural(bytes.size(), "byte") << ", version "
              << cfg::to_string(*version) << '\n';
    return;
  }
  const auto version = cfg::parse_program_version(options.version);
  if (!version) {
    fail_command("program-image", tools::kExitUsage,
                 "--version " + options.version + ": " + version.error().message);
  }
  if (options.output.empty()) {
    fail_command("program-image", tools::kExitUsage,
                 "--version needs -o IMAGE (the image is binary)");
  }
  const auto image = cfg::with_program_trailer(bytes, *version);
  if (auto written = tools::write_output(
          options.output,
          std::string_view(reinterpret_cast<const char*>(image.data()), image.size()));
      !written) {
    exit_with(tools::exit_code_for(written.error()), written.error().message);
  }
  std::cerr << options.output << ": " << tools::plural(image.size(), "byte") << ", version "
            << cfg::to_string(*version) << '\n';
}

}  // namespace

void add_program_image_command(CLI::App& app) {
  auto options = std::make_shared<ProgramImageOptions>();
  auto* cmd = app.add_subcommand(
      "program-image",
      "Build an application program image with a version trailer, or show an image's version "
      "(DSP 302 §9 program download)");
  cmd->add_option("input", options->input, "The program payload (or image), '-' for stdin")
      ->required()
      ->type_name("PAYLOAD");
  cmd->add_option("--version", options->version,
                  "Append (or replace) the 12-byte trailer with this version: "
                  "YYYY-MM-DD[THH:MM[:SS[.mmm]]] or DAYS,MS (days since 1984-01-01, ms after "
                  "midnight, as 1F52h sub 1/2 report them); without it, print the image's version")
      ->type_name("VERSION");
  cmd->add_option("-o,--output", options->output, "The image to write ('-': stdout)")
      ->type_name("IMAGE");
  cmd->footer(
      std::string(
          "The trailer is this project's convention (DSP 302 §9 leaves the image format to the\n"
          "manufacturer): date_days (UNSIGNED32 LE), time_ms (UNSIGNED32 LE), \"CPV1\". Simulated\n"
          "devices (cfgmgr simulate, sim:) report it in 1F52h once the image is started; a real\n"
          "device takes the 12 bytes as part of its image, so use it only where the device's\n"
          "format allows trailing bytes.\n\n"
          "Examples:\n"
          "  cfgmgr program-image firmware.bin --version 2026-11-27T08:15 -o drive_v2.img\n"
          "  cfgmgr program-image drive_v2.img             print the image's version\n"
          "  then in nodelist.cpj:  Node3ProgramFile=drive_v2.img\n"
          "                         Node3ProgramVersion=2026-11-27T08:15\n"
          "  or: cfgmgr push nodelist.cpj --bus sim: --program 3=drive_v2.img "
          "--program-version 3=2026-11-27T08:15\n\n") +
      std::string(tools::kExitCodesHelp));
  cmd->callback([options] { run_program_image(*options); });
}

}  // namespace cfgmgr
