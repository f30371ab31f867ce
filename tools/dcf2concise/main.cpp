// dcf2concise: DCF -> concise DCF (the 1F22h stream of DSP 302 v3.2.1 §6.2), and back to
// readable text. Argument parsing only; the work is in encode.cpp / decode.cpp and libcfg.
#include <CLI/CLI.hpp>

#include <exception>
#include <iostream>
#include <string>

#include "../common/command_failure.hpp"
#include "../common/tool_support.hpp"
#include "dcf2concise.hpp"

namespace {

int run(int argc, char** argv) {
  CLI::App app{
      "Converts a CANopen DCF (CiA 306) into the concise DCF stream a CANopen manager stores "
      "in object 1F22h (CiA 302), with PDOs written in the order DSP 302 §6.2 asks for; or "
      "decodes such a stream.",
      "dcf2concise"};
  app.footer(std::string("Examples:\n"
                         "  dcf2concise drive.dcf                      writes drive.bin\n"
                         "  dcf2concise drive.dcf -o node3.bin --node-id 3\n"
                         "  dcf2concise drive.dcf --changed-only -o - | xxd\n"
                         "  dcf2concise --decode node3.bin --dcf drive.eds\n"
                         "  dcf2concise --decode node3.bin --json\n"
                         "\n") +
             std::string(tools::kExitCodesHelp));

  app.set_version_flag("--version", tools::version_text("dcf2concise"),
                       "Print the name and version and exit");

  std::string input;
  std::string output;
  int node_id = 0;
  bool changed_only = false;
  bool with_defaults = false;
  bool strict = false;
  bool json = false;
  bool decode = false;
  std::string device_file;

  app.add_option("input", input, "DCF to convert, or with --decode the concise DCF ('-': stdin)")
      ->required()
      ->type_name("FILE");
  auto* decode_flag =
      app.add_flag("--decode", decode, "Decode a concise DCF: one line per entry on stdout");
  auto* output_opt = app.add_option("-o,--output", output,
                                    "Output file, '-' for stdout (default: the input with "
                                    "extension .bin)")
                         ->type_name("OUT");
  auto* node_opt = app.add_option("--node-id", node_id,
                                  "Node-ID for $NODEID (default: NodeID of [DeviceComissioning])")
                       ->check(CLI::Range(1, 127))
                       ->type_name("N");
  auto* changed_flag = app.add_flag("--changed-only", changed_only,
                                    "Only ParameterValues that differ from their DefaultValue");
  auto* defaults_flag =
      app.add_flag("--with-defaults", with_defaults,
                   "Also DefaultValues of writable entries that have no ParameterValue");
  changed_flag->excludes(defaults_flag);
  app.add_flag("--strict", strict,
               "Strict CiA 306 reading; warnings are errors (no output when there are any)");
  app.add_flag("--json", json, "Print a JSON summary (or the decoded entries) on stdout");
  auto* dcf_opt = app.add_option("--dcf", device_file,
                                 "With --decode: EDS/DCF giving entry names and data types")
                      ->type_name("DEVICE");
  dcf_opt->needs(decode_flag);
  for (auto* encode_only : {output_opt, node_opt, changed_flag, defaults_flag}) {
    encode_only->excludes(decode_flag);
  }

  try {
    app.parse(argc, argv);
    if (!decode && output.empty()) output = dcf2concise::default_output(input);
    if (!decode && output == input && input != "-") {
      throw CLI::ValidationError("--output", "the output would overwrite the input " + input +
                                                 "; give another one with -o");
    }
    if (json && !decode && output == "-") {
      throw CLI::ValidationError("--json",
                                 "--json prints on stdout; the stream cannot go there too");
    }
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? tools::kExitOk : tools::kExitUsage;
  }

  if (decode) return dcf2concise::run_decode({input, device_file, strict, json});
  dcf2concise::EncodeOptions options;
  options.input = input;
  options.output = output;
  if (node_opt->count() > 0) options.node_id = static_cast<std::uint8_t>(node_id);
  options.selection = changed_only    ? cfg::ConciseSelection::ChangedOnly
                      : with_defaults ? cfg::ConciseSelection::WithDefaults
                                      : cfg::ConciseSelection::Configured;
  options.strict = strict;
  options.json = json;
  return dcf2concise::run_encode(options);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const tools::CommandFailure& failure) {
    return tools::finish_command(failure);  // ended early (tools::exit_with)
  } catch (const std::exception& e) {
    // Only resource exhaustion and the like end up here; bad input is a diagnostic.
    std::cerr << "dcf2concise: error: " << e.what() << '\n';
    return tools::kExitIo;
  } catch (...) {
    std::cerr << "dcf2concise: error: unexpected exception\n";
    return tools::kExitIo;
  }
}
