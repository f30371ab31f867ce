// The file a description names, relative to the directory of the naming file: one rule for
// project files, master DCFs and bus.yml files. Private to the library.
#pragma once

#include <filesystem>
#include <string>

namespace cfg::detail {

/// `name` as a path: absolute as written, else under `base_dir` (the naming file's directory;
/// empty: as written). Tools on Windows write '\': tried as '/' when the name as written does
/// not exist.
std::string resolve_relative(const std::filesystem::path& base_dir, const std::string& name);

}  // namespace cfg::detail
