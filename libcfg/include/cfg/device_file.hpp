// Reading and writing EDS/DCF files (CiA 306). The reader collects
// diagnostics with file:line; the writer is deterministic.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "cfg/diagnostics.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/result.hpp"

namespace cfg {

/// Tolerant (default): recover from deviations real vendor files have and warn.
/// Strict (lint): every deviation from CiA 306 is an error.
/// The mode changes only the diagnostics, never the model read.
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

/// Parses EDS/DCF text. Never throws on bad input; bytes need not be valid UTF-8 (texts are kept
/// byte for byte). Lines end at LF, CRLF or CR; any line length; a UTF-8 BOM is skipped. Section
/// and key names are case-insensitive. Values are stored trimmed, with $NODEID kept as written;
/// DefaultValue/ParameterValue/LowLimit/HighLimit are checked against the DataType with
/// parse_value (node-ID 1 standing in for $NODEID). How deviations are recovered from (the full
/// list is at the top of libcfg/src/device_reader.cpp):
/// - a repeated section is merged into the first; a key given twice takes the later value;
/// - ObjectType defaults to VAR (CiA 306); missing AccessType reads as ro;
/// - an inline comment (';' or '#' after a blank) is cut from numbers, kept in strings;
/// - an empty value of a fixed-size type is "not given";
/// - objects come from their sections; the object lists are only checked against them;
/// - CompactSubObj is expanded (sub-index 0 "NrOfObjects", 1..n named "<ParameterName><n>" unless
///   [xxxxName] names them), with [xxxxValue]/[xxxxDenotation] applied.
/// Rejected (no model, one error): an empty file, and text without any [section].
ReadResult parse_device_description(std::string_view text, const ReadOptions& options = {});

/// Reads and parses a file (read_file, then parse_device_description); a file that cannot be
/// opened or read is one error diagnostic (line 0) and no model.
ReadResult read_device_file(const std::string& path, ReadOptions options = {});

/// The bytes of a whole file, read in one piece. A regular file is mapped read-only (no copy:
/// the pages are the kernel's file cache, not heap, so a model read from it stays within 3x the
/// file size); anything else (a pipe, standard input) is read into memory. Move-only; released
/// with the object. As with every mapping, a file that is truncated by another process while it
/// is mapped makes reading the vanished part fail with SIGBUS; tools read files nobody is
/// rewriting at that moment.
class FileText {
 public:
  FileText() = default;
  explicit FileText(std::string bytes);
  FileText(FileText&& other) noexcept;
  FileText& operator=(FileText&& other) noexcept;
  FileText(const FileText&) = delete;
  FileText& operator=(const FileText&) = delete;
  ~FileText();

  std::string_view view() const {
    return mapped_ != nullptr ? std::string_view(mapped_, mapped_size_) : std::string_view(buffer_);
  }
  operator std::string_view() const { return view(); }  // NOLINT(google-explicit-constructor)
  std::size_t size() const { return view().size(); }
  /// Gives the memory back now (the object is empty afterwards).
  void release();
  /// Of a mapped file, drops the pages of bytes [begin, end), both rounded down to a page, from
  /// the process's resident memory (a hint, as madvise(MADV_DONTNEED) is; the reader calls it
  /// behind itself); an `end` at or past size() drops the last page too. The bytes stay
  /// readable: a page read again comes back from the kernel's file cache. Consecutive calls,
  /// each beginning where the last ended, drop each page once.
  /// Nothing for a text read into memory.
  void release_pages(std::size_t begin, std::size_t end) const;

 private:
  friend Result<FileText> read_file(int fd);
  const char* mapped_ = nullptr;
  std::size_t mapped_size_ = 0;
  std::string buffer_;
};

/// The whole content of a file (FileText: mapped when it is a regular file, else read to its
/// end). Every tool reads its input this way; a stream iterator costs more than parsing. Fails,
/// without the path in the message (the caller names the file), with "is a directory",
/// "cannot open the file: <reason>" or "cannot read the file: <reason>".
Result<FileText> read_file(const std::string& path);
/// The same from an open descriptor (standard input: 0) to its end; the descriptor stays open
/// and owned by the caller. Fails with "cannot read the file: <reason>".
Result<FileText> read_file(int fd);

/// parse_device_description of a file as read_file read it, which gives back the pages of a
/// mapped file as the reader leaves them behind (FileText::release_pages), so that the file and
/// the model made from it are not resident together: the file's own size off a tool's peak
/// memory. `text` stays valid; bytes read again afterwards are read again from the file cache.
ReadResult parse_device_description(const FileText& text, const ReadOptions& options = {});

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
  /// With `stamp`: stamp only if the output without the stamp would differ from this text (a
  /// tool that rewrites a file marks only a real change, so a canonical file stays
  /// byte-identical). The text is only compared, during the call, and not copied; the comparison
  /// stops at the first difference, after which the stamped text is written. canonical_form()
  /// ignores it.
  std::optional<std::string_view> stamp_only_if_changed_from;
};

/// Writes the model as an EDS or DCF in canonical form: [FileInfo], [DeviceInfo], [DummyUsage],
/// [Comments], the three object lists (derived from the objects by object_list_for), the objects
/// by index each followed by its sub-objects and [xxxxObjectLinks], [DeviceComissioning] (DCF
/// only), then other_sections in model order. Deterministic: the same model and options give the
/// same bytes. An EDS gets no ParameterValue/Denotation/[DeviceComissioning].
/// CompactSubObj objects are written expanded, one [xxxxsubN] section per sub-object: the model
/// holds them expanded anyway, and the expanded form can say everything the model says (per-sub
/// names, values, limits), so it is lossless where the compact form is not. SubNumber is written
/// as the number of sub-objects. Texts are written as they are, except that line breaks become
/// blanks; keys and section names that could not be read back as themselves (empty, with '=',
/// ']' or a line break, starting with ';', '#' or '[', or an other_sections name the reader
/// interprets, like "1000" or "FileInfo") are left out.
std::string write_device_description(const DeviceDescription& device,
                                     const WriteOptions& options = {});

/// Receives a writer's text in pieces, in order (the concatenation is the file); returns false
/// to stop the writer, e.g. after a write error.
using TextSink = std::function<bool(std::string_view piece)>;

/// The same text as write_device_description() above, handed to `sink` in pieces of about
/// 64 KiB as it is made, so that a large file is written without its whole text in memory. With
/// `stamp_only_if_changed_from`, the unstamped text is first compared with that text as it is
/// made (up to the first difference); when they are the same, `sink` gets that text itself.
/// Returns false when the sink stopped it.
bool write_device_description(const DeviceDescription& device, const WriteOptions& options,
                              const TextSink& sink);

/// The model as write_device_description() with these options represents it, i.e. what reading
/// its output back gives (ignoring `line` fields): FileInfo stamped, CompactSubObj expanded
/// (compact_sub_obj unset, sub_number = number of sub-objects), VAR entries named and typed like
/// their object and without sub-objects beyond 0, values stored as the reader stores them
/// (trimmed, comments cut from numbers, empty fixed-size values dropped), duplicate keys and
/// other_sections merged, unwritable keys/sections dropped; for FileKind::Eds no ParameterValue,
/// Denotation or commissioning. For models read from files this is the round-trip contract:
/// parse(write(m, o)) == canonical_form(m, o).
DeviceDescription canonical_form(DeviceDescription device, const WriteOptions& options = {});

}  // namespace cfg
