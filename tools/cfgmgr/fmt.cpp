// cfgmgr fmt IN [-o OUT]: write an EDS/DCF back in canonical form (libcfg's writer: sections in
// a fixed order, objects by index, object lists derived from the objects).
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "../common/tool_support.hpp"
#include "cfg/device_file.hpp"
#include "cfg/object_dictionary.hpp"
#include "commands.hpp"

namespace cfgmgr {
namespace {

struct FmtOptions {
  std::string input;
  std::string output = "-";
  bool eds = false;
  bool dcf = false;
  bool lf = false;
  bool no_stamp = false;
};

// When fmt changes a file it says so in [FileInfo] (CiA 306 ModifiedBy, ModificationDate/Time),
// as an editing tool does. The time is SOURCE_DATE_EPOCH when set (reproducible output), else now.
cfg::WriteOptions::Stamp stamp_now() {
  cfg::WriteOptions::Stamp stamp;
  stamp.modified_by = "cfgmgr";
  if (const char* epoch = std::getenv("SOURCE_DATE_EPOCH"); epoch != nullptr && *epoch != 0) {
    char* end = nullptr;
    const long long seconds = std::strtoll(epoch, &end, 10);
    if (end != nullptr && *end == 0) {
      stamp.unix_time_s = seconds;
      return stamp;
    }
  }
  stamp.unix_time_s = std::chrono::duration_cast<std::chrono::seconds>(
                          std::chrono::system_clock::now().time_since_epoch())
                          .count();
  return stamp;
}

void run_fmt(const FmtOptions& options) {
  // One read of the file: parsed, and compared with the output below.
  auto input = tools::read_input(options.input);
  if (!input) {
    exit_with(tools::exit_code_for(input.error()), input.error().message);
  }
  cfg::ReadOptions read_options;
  read_options.file_name = options.input;
  auto read = cfg::parse_device_description(*input, read_options);
  tools::print_diagnostics(read.diagnostics);
  if (!read.ok()) exit_with(tools::kExitInputErrors);

  cfg::WriteOptions write_options;
  if (options.eds || options.dcf) {
    write_options.kind = options.eds ? cfg::FileKind::Eds : cfg::FileKind::Dcf;
  } else {
    // Same kind as the input, by its extension.
    const auto ext = std::filesystem::path(options.input).extension().string();
    write_options.kind = cfg::iequals(ext, ".eds") ? cfg::FileKind::Eds : cfg::FileKind::Dcf;
  }
  write_options.line_ending = options.lf ? cfg::LineEnding::Lf : cfg::LineEnding::Crlf;
  // Stamp only a real change, so that formatting a canonical file leaves it byte-identical.
  if (!options.no_stamp) {
    write_options.stamp = stamp_now();
    write_options.stamp_only_if_changed_from = input->view();
  }
  // The text goes to the output in blocks as it is made (never whole in memory); the output
  // replaces the old file only once complete.
  auto output = tools::OutputFile::open(options.output);
  if (!output) {
    exit_with(tools::exit_code_for(output.error()), output.error().message);
  }
  cfg::Status written;
  cfg::write_device_description(*read.device, write_options, [&](std::string_view piece) {
    written = output->write(piece);
    return written.ok();
  });
  if (written) written = output->commit();
  if (!written) {
    exit_with(tools::exit_code_for(written.error()), written.error().message);
  }
  tools::keep_until_exit(std::move(read));  // the process exits next: the model goes with it
}

}  // namespace

void add_fmt_command(CLI::App& app) {
  auto options = std::make_shared<FmtOptions>();
  auto* cmd = app.add_subcommand(
      "fmt", "Write an EDS/DCF back in canonical form (CiA 306; CRLF unless --lf)");
  cmd->add_option("input", options->input, "EDS or DCF file")->required()->type_name("IN");
  cmd->add_option("-o,--output", options->output, "Output file, '-' for stdout (default)")
      ->type_name("OUT");
  auto* eds = cmd->add_flag("--eds", options->eds,
                            "Write an EDS (no ParameterValue, Denotation, [DeviceComissioning])");
  auto* dcf = cmd->add_flag("--dcf", options->dcf, "Write a DCF");
  eds->excludes(dcf);
  cmd->add_flag("--lf", options->lf, "LF line endings instead of CRLF");
  cmd->add_flag("--no-stamp", options->no_stamp,
                "Leave [FileInfo] as it is (default: when the output differs from the input, set "
                "ModifiedBy=cfgmgr and ModificationDate/Time, from SOURCE_DATE_EPOCH if set)");
  cmd->footer(std::string("The kind of output defaults to the input's (by extension .eds/.dcf).\n"
                          "An input with errors is not written; warnings are printed.\n\n"
                          "Examples:\n"
                          "  cfgmgr fmt vendor.eds -o clean.eds\n"
                          "  cfgmgr fmt node3.dcf -o node3.dcf        rewrite in place\n"
                          "  cfgmgr fmt node3.dcf --eds --lf > device.eds\n\n") +
              std::string(tools::kExitCodesHelp));
  cmd->callback([options] { run_fmt(*options); });
}

}  // namespace cfgmgr
