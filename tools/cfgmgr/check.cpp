// cfgmgr check FILE...: read EDS/DCF files (CiA 306), check them against the CiA 301/302 object
// definitions in schemas/, and print every diagnostic. Exit 0 when nothing is an error.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/device_file.hpp"
#include "cfg/schema.hpp"
#include "commands.hpp"

namespace cfgmgr {
namespace {

struct CheckOptions {
  std::vector<std::string> files;
  bool strict = false;
  bool json = false;
  bool no_schema = false;
  std::string schema_dir;
};

struct FileReport {
  std::string file;
  bool readable = true;
  std::size_t objects = 0;
  cfg::Diagnostics diagnostics;
};

std::string json_report(const std::vector<FileReport>& reports, bool ok) {
  std::string out = "{\"ok\": " + std::string(ok ? "true" : "false") + ", \"files\": [";
  bool first = true;
  for (const auto& r : reports) {
    if (!first) out += ", ";
    first = false;
    const auto& d = r.diagnostics;
    out += "{\"file\": " + tools::json_string(r.file) +
           ", \"readable\": " + (r.readable ? "true" : "false") +
           ", \"ok\": " + (r.readable && !d.has_errors() ? "true" : "false") +
           ", \"objects\": " + std::to_string(r.objects) +
           ", \"errors\": " + std::to_string(d.count(cfg::Severity::Error)) +
           ", \"warnings\": " + std::to_string(d.count(cfg::Severity::Warning)) +
           ", \"notes\": " + std::to_string(d.count(cfg::Severity::Note)) +
           ", \"diagnostics\": " + tools::json_diagnostics(d) + "}";
  }
  return out + "]}\n";
}

// True for a path whose extension is .dcf (any case): CiA 306 §2 names DCFs by it.
bool has_dcf_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".dcf";
}

void run_check(const CheckOptions& options) {
  if (std::count(options.files.begin(), options.files.end(), "-") > 1) {
    std::cerr << "cfgmgr check: error: '-' (stdin) can be given only once\n";
    exit_with(tools::kExitUsage);
  }
  // The standard's object definitions: from --schema-dir, else as cfg::find_schema_dir() finds
  // them ($CANOPEN_SCHEMA_DIR, or installed beside the program). Never skipped silently: when
  // they cannot be had the check fails (exit 3, before any file is read); --no-schema opts out.
  std::vector<cfg::DeviceDescription> schemas;
  if (!options.no_schema) {
    const bool asked = !options.schema_dir.empty();
    std::string dir = options.schema_dir;
    if (!asked) {
      auto found = cfg::find_schema_dir();
      if (!found) {
        std::cerr << "cfgmgr check: error: " << found.error().message
                  << "; give --schema-dir DIR, or --no-schema to check without them\n";
        exit_with(tools::kExitIo);
      }
      dir = std::move(found).value();
    }
    for (auto name : cfg::kStandardSchemas) {
      auto schema = cfg::load_schema(name, dir);
      if (!schema) {
        // The message may end with the schema file's diagnostics, one a line.
        std::string why = schema.error().message;
        while (!why.empty() && why.back() == '\n') why.pop_back();
        std::cerr << "cfgmgr check: error: " << (asked ? "--schema-dir " : "schema directory ")
                  << dir << ": cannot load schema " << name << ": " << why << '\n';
        exit_with(tools::kExitIo);
      }
      schemas.push_back(std::move(schema).value());
    }
  }

  std::vector<FileReport> reports;
  bool any_unreadable = false;
  bool any_errors = false;
  for (const auto& file : options.files) {
    FileReport report;
    const bool from_stdin = file == "-";
    report.file = from_stdin ? "<stdin>" : file;
    cfg::ReadOptions read_options;
    read_options.mode = options.strict ? cfg::ReadMode::Strict : cfg::ReadMode::Tolerant;
    read_options.file_name = report.file;
    auto text = tools::read_input(file);
    if (!text) {
      std::cerr << text.error().message << '\n';
      report.readable = false;
      any_unreadable = true;
      reports.push_back(std::move(report));
      continue;
    }
    auto read = cfg::parse_device_description(*text, read_options);
    text->release();  // the model holds copies: give the file's bytes back now
    report.diagnostics = read.diagnostics;
    if (read.device) {
      report.objects = read.device->objects.size();
      for (const auto& schema : schemas) {
        cfg::check_against_schema(*read.device, schema, report.file, report.diagnostics);
      }
      // CiA 306 §4.7: a DCF describes one configured node, so it says which node-ID it is for.
      if (has_dcf_extension(file) && !read.device->node_id()) {
        report.diagnostics.add(report.file, 0, cfg::Severity::Warning,
                               "a DCF should give the node-ID in [DeviceComissioning] NodeID "
                               "(CiA 306)");
      }
    } else if (!report.diagnostics.has_errors()) {
      report.diagnostics.add(report.file, 0, cfg::Severity::Error, "not a device description");
    }
    // Strict is lint: every warning is an error, as with -Werror.
    if (options.strict) report.diagnostics = tools::promote_warnings(report.diagnostics);
    tools::print_diagnostics(report.diagnostics);
    any_errors = any_errors || report.diagnostics.has_errors();
    if (!options.json) {
      std::cout << report.file << ": "
                << tools::plural(report.diagnostics.count(cfg::Severity::Error), "error") << ", "
                << tools::plural(report.diagnostics.count(cfg::Severity::Warning), "warning")
                << ", " << tools::plural(report.objects, "object") << '\n';
    }
    reports.push_back(std::move(report));
  }
  if (options.json) std::cout << json_report(reports, !any_unreadable && !any_errors);
  std::cout.flush();
  if (any_unreadable) exit_with(tools::kExitIo);
  if (any_errors) exit_with(tools::kExitInputErrors);
}

}  // namespace

void add_check_command(CLI::App& app) {
  auto options = std::make_shared<CheckOptions>();
  auto* cmd = app.add_subcommand(
      "check",
      "Read EDS/DCF files, check them against the CiA 301/302 object definitions, and print "
      "every diagnostic (FILE:LINE: severity: message) on stderr");
  cmd->add_option("files", options->files, "EDS or DCF files ('-': stdin)")
      ->required()
      ->type_name("FILE");
  cmd->add_flag("--strict", options->strict,
                "Lint: every deviation from CiA 306 and every warning is an error");
  cmd->add_flag("--json", options->json, "Print the result as JSON on stdout");
  cmd->add_option("--schema-dir", options->schema_dir,
                  "Directory of the schema EDS files (default: $CANOPEN_SCHEMA_DIR, else "
                  "share/canopen/schemas of the installation)")
      ->type_name("DIR");
  cmd->add_flag("--no-schema", options->no_schema,
                "Do not check against the CiA 301/302 object definitions");
  cmd->footer(std::string("Examples:\n"
                          "  cfgmgr check drive.eds\n"
                          "  cfgmgr check --strict network/*.dcf\n"
                          "  cfgmgr check --json node3.dcf | jq .files[0].errors\n\n") +
              std::string(tools::kExitCodesHelp));
  cmd->callback([options] { run_check(*options); });
}

}  // namespace cfgmgr
