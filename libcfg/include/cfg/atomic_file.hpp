// Crash-safe replacement of a whole file: the configuration manager's store writes its entries
// this way (config_manager.hpp), and so may anything else that must never leave half a file.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "cfg/result.hpp"

namespace cfg {

/// Replaces `directory`/`name` atomically: a temporary file ".<name>.<pid>.tmp" in `directory`
/// is written and fsync'd, renamed over `name` (rename(2): a reader, or a restart after a crash,
/// sees the old or the new file, never a mix), then the directory is fsync'd. `directory` must
/// exist. Fails (ErrorCategory::Io) naming the file and the reason; the old file is then
/// untouched.
Status write_file_atomically(const std::string& directory, const std::string& name,
                             std::span<const std::uint8_t> bytes);

}  // namespace cfg
