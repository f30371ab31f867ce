// Reading and writing EDS/DCF files (CiA 306). The reader is built on inih and collects
// diagnostics with file:line; the writer is deterministic.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "cfg/diagnostics.hpp"
#include "cfg/object_dictionary.hpp"

namespace cfg {

/// Tolerant (default): recover from deviations real vendor files have and warn.
/// Strict (lint): every deviation from CiA 306 is an error.
enum class ReadMode { Tolerant, Strict };

struct ReadOptions {
  ReadMode mode = ReadMode::Tolerant;
  /// Name used in diagnostics (the path for read_device_file; e.g. "<stdin>" for text).
  std::string file_name;
};

struct ReadResult {
  /// The model, unless the input could not be understood at all (then diagnostics say why).
  /// In strict mode a model is still returned when there are errors, for tools that want it.
  std::optional<DeviceDescription> device;
  Diagnostics diagnostics;

  bool ok() const { return device.has_value() && !diagnostics.has_errors(); }
};

/// Parses EDS/DCF text. Never throws on bad input; bytes need not be valid UTF-8.
ReadResult parse_device_description(std::string_view text, const ReadOptions& options = {});

/// Reads and parses a file; a file that cannot be opened is an error diagnostic.
ReadResult read_device_file(const std::string& path, ReadOptions options = {});

enum class FileKind { Eds, Dcf };
enum class LineEnding { Crlf, Lf };

struct WriteOptions {
  FileKind kind = FileKind::Dcf;
  LineEnding line_ending = LineEnding::Crlf;  ///< CiA 306 files are CRLF by convention
  /// When set, [FileInfo] ModificationTime/ModificationDate are set from it ("hh:mmAM",
  /// "mm-dd-yyyy" per CiA 306) and ModifiedBy to `modified_by`; CreatedBy/Creation* are kept,
  /// or filled from these when the file has none. Unset: FileInfo is written as it is, so output
  /// depends only on the model (deterministic).
  struct Stamp {
    std::int64_t unix_time_s = 0;
    std::string modified_by;
  };
  std::optional<Stamp> stamp;
};

/// Writes the model as an EDS or DCF in canonical form: sections in a fixed order, objects by
/// index, object lists derived from the objects, CompactSubObj expanded. An EDS gets no
/// ParameterValue/Denotation/[DeviceComissioning].
std::string write_device_description(const DeviceDescription& device,
                                     const WriteOptions& options = {});

}  // namespace cfg
