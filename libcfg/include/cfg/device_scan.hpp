// What a scan of a live network (`cfgmgr scan`) makes of what it read: the EDS that describes
// each device found (a library of vendor EDS files, matched on 1018h), the entries to read from
// it, the as-found DCF that records what the device holds, and the CiA 306-3 project naming the
// DCFs, so that `cfgmgr push` of that project commissions replacement devices at factory
// defaults into the state the scanned ones were in. No bus I/O and no clocks here: the tool
// uploads the values (SDO) and writes the files.
//
// The identity a push checks (CiA 302-2 §3.4 e, the master's 1F84h-1F87h derived by
// derive_master of cfg/network.hpp): device type (1000h), vendor-ID, product code and revision
// (1018h sub 1-3) as the scanned device reported them. The boot accepts a revision whose major
// part (high 16 bits) equals and whose minor part (low 16 bits) is not lower than the recorded
// one (CiA 302-2 §6.9, libnmt/core/src/master/boot_slave.cpp), so a replacement with a newer
// minor revision (backward compatible by CiA 301 §7.5.2.23) passes and an older one, which may
// lack what the scanned device was configured with, is refused (status N; tests/nmt's
// NmtMasterSpec.RevisionWithEqualMajorAndEqualOrHigherMinorPasses). The serial number
// (1018h sub 4) is never recorded in a DCF: a replacement has another one (derive_master keeps
// 1F88h 0 anyway).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "cfg/diagnostics.hpp"
#include "cfg/network.hpp"  // DeviceIdentity: 1000h, 1018h sub 1-4 of one device
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_dictionary.hpp"

namespace cfg {

/// A device's identity as a scan reads it is cfg::DeviceIdentity (cfg/network.hpp): 1000h and
/// 1018h sub 1-4, nullopt for what the device did not answer (an absent sub-index).

/// Vendor EDS files, read once, matched against what devices report.
///
/// Which files: every regular file under the directory (recursively, symbolic links to files
/// followed, to directories not) whose name ends in ".eds" in any case. DCFs (*.dcf) are not
/// taken: a DCF describes one configured node of some project, and its ParameterValues,
/// [DeviceComissioning] and values for entries a scan does not read would end up in the as-found
/// DCF; a scan's own output (nodeN.dcf) under the same directory would also match itself. A
/// vendor that ships only a DCF is added with add() by the caller who chose it.
class EdsLibrary {
 public:
  /// The outcome of match(): the file to use and how well it fits.
  struct Match {
    const DeviceDescription* eds = nullptr;  ///< owned by the library; valid while it lives
    std::string path;                        ///< the file's path as loaded (or as add() named it)
    bool revision_exact = false;  ///< the file's revision equals the device's 1018h sub 3
    /// Empty when exact; else why this file: "revision 0x00020003 not in the library; nearest
    /// 0x00020001 (same major revision, lower minor) in a/b.eds".
    std::string note;
  };

  /// Reads every *.eds under `directory` in sorted path order (deterministic). A file that
  /// cannot be read or has errors (tolerant reading, cfg/device_file.hpp) is skipped: each of
  /// its errors goes into `diagnostics` as a WARNING at its file:line, followed by one warning
  /// "not in the EDS library" for the file, so that a broken vendor file does not fail a scan of
  /// devices it does not describe (the device it would have described is reported by missing()).
  /// The tolerant reader's warnings of the files loaded are not repeated (`cfgmgr check FILE`
  /// shows them). A directory that cannot be read is an error (line 0).
  static EdsLibrary load(const std::string& directory, Diagnostics& diagnostics);

  /// Adds one description already read (e.g. the EDS a device stores in 1021h, read with
  /// parse_device_description): `path` names it in notes and in missing(). Its ParameterValues
  /// and [DeviceComissioning] are dropped, so that it is used as an EDS.
  void add(DeviceDescription eds, std::string path);

  /// The file for a device: vendor-ID and product code equal (the device's 1018h sub 1/2 against
  /// the file's [DeviceInfo] VendorNumber/ProductNumber or its 1018h sub 1/2 DefaultValue; a
  /// file matches by either, 0 standing for "not given"). Among those, the file whose revision
  /// ([DeviceInfo] RevisionNumber, else 1018h sub 3 DefaultValue) equals 1018h sub 3; else the
  /// nearest by CiA 301 §7.5.2.23 (major = high 16 bits, minor = low 16 bits):
  ///  1. same major, the highest minor below the device's (the device is a compatible superset
  ///     of what that file describes);
  ///  2. same major, the lowest minor above;
  ///  3. another major: the smallest distance |file - device| of the 32-bit numbers, the lower
  ///     on a tie;
  ///  4. files that give no revision last.
  /// A device without 1018h sub 3 takes the highest revision. Equal candidates: the first path.
  /// nullopt when no file has that vendor-ID and product code (or the identity lacks either).
  std::optional<Match> match(const DeviceIdentity& identity) const;

  /// The line a user reads when match() finds none, naming the EDS to provide: "no EDS for
  /// vendor-ID 0x0000003F, product code 0x00000409, revision 0x01190528; the library has, of
  /// the same vendor, other products: 0x002DCAA8 rev 0x01400538 (systec/io.eds)" or "...; the
  /// library has no file of vendor-ID 0x0000003F (4 files)".
  std::string missing(const DeviceIdentity& identity) const;

  std::size_t size() const { return files_.size(); }

 private:
  struct File {
    std::string path;
    DeviceDescription eds;
    std::vector<std::uint32_t> vendor_ids;     // the numbers the file gives, non-zero
    std::vector<std::uint32_t> product_codes;  // ditto
    std::optional<std::uint32_t> revision;
  };
  // A deque: add() keeps the addresses of the files already in Match::eds.
  std::deque<File> files_;
};

/// The entries a scan uploads from a device `eds` describes, in index/sub-index order: every
/// sub-object of 1000h-FFFFh with AccessType rw or rwr (one may read and write it; ro, const
/// and wo are not configuration) and a basic, decodable data type, including sub-index 0
/// of an array/record when it is writable (a PDO mapping's count, CiA 301 §7.5.2.36), the PDO
/// communication (1400h-15FFh, 1800h-19FFh) and mapping (1600h-17FFh, 1A00h-1BFFh) parameters.
/// Left out:
///  - rww entries: CiA 306 marks process outputs so (RPDO-mappable, "write on process output");
///    writing a scanned output value into a replacement during its configuration would switch
///    that output (a digital output, a drive's target) before the application runs;
///  - 1003h (sub 0 is rw, but a write of 0 clears the error history and any other value is
///    refused, CiA 301 §7.5.2.3);
///  - 1010h/1011h (store/restore: a write is a command, CiA 301 §7.5.2.13/14) and 1F51h
///    (program control: a write stops, starts or clears the program, DSP 302 §9);
///  - 1020h (verify configuration): the master writes its own stamp after a download (CiA
///    302-2 §3.5), the old device's date means nothing to a replacement;
///  - DOMAIN entries (object type or data type): program data and vendor blobs, of any size,
///    often write-only in effect or a command (a domain upload may start a transfer of
///    megabytes); a DCF would need a DownloadFile for each (not a scan's business);
///  - entries with CiA 306 ObjFlags bit 1 ("refuse read on scan"), on the sub-object or its
///    object.
std::vector<ObjectAddress> entries_to_scan(const DeviceDescription& eds);

/// The DCF's [FileInfo] FileName and the project's NodeXDCFName for node N: "nodeN.dcf".
std::string scan_dcf_file_name(NodeId node);

/// The as-found DCF of node `node`: `eds` as a DCF ([DeviceComissioning] NodeID=N, NodeName
/// = [DeviceInfo] ProductName (else "node N"), [FileInfo] FileName=nodeN.dcf, the EDS's own
/// ParameterValues and Denotations dropped) with a ParameterValue for every entry in `values`,
/// the bytes an SDO upload of it returned (little-endian, the size of the entry's data type),
/// written by format_value. Rules:
///  - an entry whose EDS DefaultValue uses $NODEID (1014h, 1200h sub 1/2, the pre-defined PDO
///    COB-IDs) gets no ParameterValue when the value read equals that default for node N: the
///    device derives it from its node-ID (CiA 301 §7.3.5), and the DCF keeps "$NODEID+..." so
///    that it stays right at another node-ID. A value that differs (a disabled PDO, bit 31, or
///    another COB-ID) is recorded as read;
///  - 1000h and 1018h sub 1-3 are recorded as read (added to 1018h when the EDS lacks them):
///    the identity the master checks (see the top); 1018h sub 0 and sub 4 (the serial number)
///    are ignored;
///  - an entry that is not in `eds`, is not one entries_to_scan() gives (nor the identity), or
///    whose bytes are not a value of its type (wrong size, a BOOLEAN of 2), is left out with a
///    warning naming it (file "", line 0).
DeviceDescription as_found_dcf(const DeviceDescription& eds, NodeId node,
                               const std::map<ObjectAddress, std::vector<std::uint8_t>>& values,
                               Diagnostics& diagnostics);

/// The DCF of a device no EDS in the library describes: 1000h and 1018h sub 0-3 as found (ro,
/// ParameterValue; absent ones left out, sub 0 = the highest given), 1001h, [DeviceInfo]
/// VendorNumber/ProductNumber/RevisionNumber and [DeviceComissioning] NodeID=N. A push of a
/// project naming it checks the identity (derive_master) and writes nothing.
DeviceDescription identity_only_dcf(NodeId node, const DeviceIdentity& identity);

/// One node of a scanned project.
struct ScanProjectNode {
  NodeId node;
  std::string dcf_file;  ///< NodeXDCFName, relative to the project file (scan_dcf_file_name)
  std::string name;      ///< NodeXName; empty: no NodeXName (the DCF's NodeName stands)
};

/// The text of a CiA 306-3 project file (nodelist.cpj, CRLF lines): [Topology] NetName,
/// Nodes (the count, hex), and per node NodeXPresent=0x01, NodeXName, NodeXDCFName, by
/// ascending node-ID. load_network reads it (cfg/network.hpp).
std::string scan_project(std::string_view net_name, std::vector<ScanProjectNode> nodes);

}  // namespace cfg
