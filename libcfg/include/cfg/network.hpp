// The network description a CANopen manager works from: which nodes there are, what each is
// configured with, and the master's own dictionary, which rules the boot (CiA 302-2 §3, DSP 302
// §6). Two forms are read:
//  - a CiA 306-3 project file (`nodelist.cpj`): `[Topology]` (further networks `[Topology2]`,
//    `[Topology3]`...) with NetName, Nodes, NodeXPresent, NodeXName, NodeXDCFName, EDSBaseName,
//    X being the node-ID in decimal; each present node's DCF path is relative to the project
//    file's directory (an absolute path is taken as it is; '\' separators of Windows tools are
//    tried as '/' when the path as written does not exist). Our own keys (CiA 306-3 has none for
//    a node's application program, DSP 302 §9): NodeXProgramFile= names the image the node
//    should run (relative as NodeXDCFName) and NodeXProgramVersion= its version (1F53h/1F54h
//    sub X, cfg::parse_program_version's text); see "the application program" below. A DCF whose
//    [DeviceComissioning] has CANopenManager=1 is the master's own: its
//    1F80h/1F81h/1F84h-1F8Ah/1016h/1F26h/1F27h rule the boot; without one the master's dictionary
//    is derived (derive_master, below);
//  - a master DCF alone (CANopenManager=1): its 1F20h sub X (a DCF) or 1F22h sub X (a concise
//    DCF, or a DCF) name node X's file, relative to the master DCF, and 1F58h sub X (CiA 302-3
//    program data) the image of node X's program (NetworkNode::program, without a version: the
//    master DCF's 1F53h/1F54h give it). A DOMAIN's file is named by DownloadFile= (CiA 306: the
//    file whose content is downloaded into the domain) or UploadFile= (the file the domain's
//    content is read from when it is uploaded, as lely-core's master reads it; lely's dcfgen
//    writes only this one); both name the content of the master's own entry, DownloadFile= wins
//    when both are given. A node X in 1F81h whose 1F20h/1F22h sub X name no file is not in
//    `nodes`: the master has no configuration for it. A named file that does not exist as
//    written (dcfgen writes absolute paths of the machine that built the files) is looked for
//    by its name alone in NetworkOptions::dcf_path, then beside the master DCF (a warning names
//    both paths); found nowhere, it is an error at the key's line. A 1F58h sub X for a node
//    without a 1F20h/1F22h file is a warning and not used.
// A third form, lely dcfgen's and ros2_canopen's bus.yml, is read into the same model by
// cfg/bus_yml.hpp. No bus I/O, no clocks: files are read once by load_network.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "cfg/diagnostics.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/program_image.hpp"

namespace cfg {

/// A node's application program (DSP 302 §9) as the network description (or a command line)
/// gives it: the image the master downloads to 1F50h sub 1 when 1F52h differs from the
/// expected version, and that version (the master's 1F53h/1F54h sub node-ID).
struct NodeProgram {
  /// The image's path as opened; empty when only the version is given (the master checks the
  /// version, 1F81h bit 5, but may not update: status H when it differs).
  std::string file;
  /// The image's bytes, read by load_network (or set_node_program) once, so that the master
  /// never reads a file while it runs.
  std::vector<std::uint8_t> image;
  /// The expected version; nullopt only for a node whose version the master DCF's 1F53h/1F54h
  /// give (master DCF form), not the description.
  std::optional<ProgramVersion> version;
  /// CiA 302-3: the expected software identification (1F55h sub N), compared with the slave's
  /// 1F56h sub 1 instead of 1F52h against the version (as lely-core's master does; dcfgen's
  /// `software_version`). Nonzero when set.
  std::optional<std::uint32_t> identification;
  std::string source;  ///< the file that names the program ("" for a command line)
  int line = 0;        ///< the line of NodeXProgramFile= (else NodeXProgramVersion=)
};

/// One slave of the network.
struct NetworkNode {
  NodeId node_id = *NodeId::from(1);
  std::string name;  ///< NodeXName, else the DCF's NodeName; may be empty
  std::string file;  ///< the node's file as opened (relative paths joined to the description's)
  /// The node's DCF; nullopt when the node is given by a concise DCF alone (master DCF form).
  std::optional<DeviceDescription> dcf;
  /// What configures the node: the DCF's ParameterValues (concise_writes_from_dcf, PDO-safe
  /// order, $NODEID resolved with node_id) or the concise DCF's entries as stored. Never 1020h
  /// or 1010h: the master adds them after the download (CiA 302-2 §3.5).
  std::vector<ObjectWrite> writes;
  /// The application program the node should run; nullopt: the description says none.
  std::optional<NodeProgram> program;
};

/// A loaded network description.
struct Network {
  std::string file;  ///< the description's path as given
  std::string name;  ///< NetName, else the master DCF's NetworkName; may be empty
  /// EDSBaseName (where the devices' EDSs are) joined to the project file's directory; empty
  /// when not given. Not read by load_network: a DCF is complete without its EDS.
  std::string eds_base_dir;
  unsigned net = 1;  ///< the [Topology] read (1: [Topology], n: [Topology<n>])
  /// The slaves, by ascending node-ID; never the master itself.
  std::vector<NetworkNode> nodes;
  /// The master's dictionary: its DCF (master_from_file), else derive_master(nodes).
  DeviceDescription master;
  bool master_from_file = false;
  std::string master_file;  ///< the master DCF's path when master_from_file
  /// The master's node-ID: its topology entry, else its DCF's NodeID; nullopt when neither
  /// says (a tool picks its default).
  std::optional<NodeId> master_node_id;

  /// The slave with this node-ID, or nullptr.
  const NetworkNode* find(NodeId node) const;
};

struct NetworkOptions {
  /// Which network of a project file: 1 reads [Topology], n > 1 [Topology<n>].
  unsigned net = 1;
  /// How the DCFs are read (cfg/device_file.hpp); the project file's own checks are the same
  /// in both modes.
  ReadMode mode = ReadMode::Tolerant;
  /// Directories where a file a master DCF names (1F20h/1F22h/1F58h) is looked for by its name
  /// alone when it does not exist as written, in order (lely's dcfgen calls the directory it
  /// writes into the master DCF's paths `dcf_path`); the master DCF's directory comes after.
  std::vector<std::string> dcf_path;
  /// How the caller's user gives such a directory (e.g. "pass it with --dcf-path DIR"), ending
  /// the error for a file found nowhere. Empty: the message says "pass the directory".
  std::string dcf_path_hint;
  /// Values of `@NAME@` placeholders (CMake configure_file's) in a bus.yml's paths, by NAME
  /// (cfg/bus_yml.hpp); unused by the other forms.
  std::map<std::string, std::string> placeholders;
};

struct NetworkLoad {
  /// The network, unless the description could not be understood at all (unreadable file,
  /// neither a project file nor a master DCF, no such [Topology<n>]).
  std::optional<Network> network;
  /// Every file's diagnostics with file:line: the project file's own (missing DCF, node-ID
  /// clashes, bad values) and each DCF's reader and configuration diagnostics. A node whose
  /// file has errors is left out of `nodes`.
  Diagnostics diagnostics;
  /// The description file itself could not be read (missing, a directory, no permission): an
  /// I/O error rather than an error of its content.
  bool unreadable = false;
  bool ok() const { return network.has_value() && !diagnostics.has_errors(); }
};

/// Reads a network description (either form, told apart by content: a project file has a
/// [Topology] section; a path ending in .yml/.yaml is a lely/ros2_canopen bus.yml, read by
/// load_bus_yml of cfg/bus_yml.hpp into the same model). Never throws on bad input. Reported as
/// errors: a file that cannot be read (at the line naming it), a NodeXPresent/Nodes value that is
/// not a number, a present node without NodeXDCFName, a DCF whose [DeviceComissioning] NodeID
/// differs from the node-ID the project file (or the 1F20h/1F22h sub-index) gives it, two DCFs with
/// CANopenManager=1, a DCF value that cannot be encoded. Warnings: Nodes differing from the number
/// of present nodes.
NetworkLoad load_network(const std::string& path, const NetworkOptions& options = {});

// --- the derived master --------------------------------------------------------------------------
// Without a master DCF, the master's dictionary follows from the nodes' DCFs:
//  - 1F80h = 1 (NMT master; it enters operational by itself and starts every slave
//    individually once booted, CiA 302-2 §6.2 bits 1-3 = 0);
//  - 1F81h sub X = bits 0, 2, 3 (slave, boot and start it, mandatory) for every node X, with,
//    when the node produces no heartbeat but its DCF configures node guarding (100Ch guard
//    time and 100Dh life time factor both non-zero), byte 1 = 100Dh and bytes 2-3 = 100Ch;
//  - 1F84h sub X = 1000h, 1F85h/1F86h/1F87h sub X = 1018h sub 1/2/3, each the DCF's
//    ParameterValue, else DefaultValue, else [DeviceInfo] VendorNumber/ProductNumber/
//    RevisionNumber (none for 1000h); 0 (not checked) when none is given; 1F88h (serial number)
//    stays 0, as a serial number belongs to one device, not to its configuration;
//  - 1F26h/1F27h sub X = configuration_stamp() of the node's writes as a concise DCF, so that
//    any change of a downloaded value (or of the set of values) changes them and the next boot
//    downloads again, while an unchanged configuration is skipped (1020h matches); 0 (not
//    verified: downloaded at every boot, 1020h not written) for a node whose DCF has no
//    writable 1020h sub 1/2, which would refuse the master's 1020h writes;
//  - 1016h: one heartbeat consumer entry per node whose 1017h (its writes' value, else the
//    DCF's) is non-zero, with heartbeat_consumer_time_ms() of it.
// Every array has sub-indices 0..127 (sub 0 = 7Fh), unused entries 0.

/// What a device described by `dcf` reports as its identity, as derive_master expects it and
/// a simulated device of the DCF answers: 1000h, 1018h sub 1-3 (ParameterValue, else
/// DefaultValue, $NODEID resolved with `node`), else [DeviceInfo] VendorNumber/ProductNumber/
/// RevisionNumber; nullopt where neither says.
struct DeviceIdentity {
  std::optional<std::uint32_t> device_type;
  std::optional<std::uint32_t> vendor_id;
  std::optional<std::uint32_t> product_code;
  std::optional<std::uint32_t> revision_number;
  /// 1018h sub 4 as the device's LSS address has it (CiA 305): [DeviceComissioning]
  /// LSS_SerialNumber, else 1018h sub 4's ParameterValue/DefaultValue. derive_master leaves
  /// 1F88h 0 all the same (see above).
  std::optional<std::uint32_t> serial_number;
  bool operator==(const DeviceIdentity&) const = default;
};
DeviceIdentity identity_of(const DeviceDescription& dcf, NodeId node);

/// The unsigned value (up to 32 bits) `node` has in an entry after its configuration: its write
/// of the entry, else its DCF's ParameterValue, else DefaultValue ($NODEID resolved with its
/// node-ID); nullopt when neither has one (1014h of a node without it: 80h + node-ID applies).
std::optional<std::uint32_t> configured_value(const NetworkNode& node, std::uint16_t index,
                                              std::uint8_t sub_index);

/// A node's concise DCF: its writes in the network's (PDO-safe) order as a DSP 302 §6.2 stream.
/// The one encoding of a node's configuration: `cfgmgr build` writes it as nodeN.bin, the
/// derived master's 1F26h/1F27h are its configuration_stamp, and the configuration manager
/// (`cfgmgr master`) serves it as 1F22h sub node-ID when nothing is stored for the node.
std::vector<std::uint8_t> node_concise_dcf(const NetworkNode& node);

/// A valid 1020h/1F26h/1F27h date and time standing for a configuration: h = the 64-bit FNV-1a
/// hash of `concise_dcf` (the stream encode_concise_dcf makes of the writes);
/// days = 5844 + (h >> 32) mod 18263 (a day from 1 January 2000 to 31 December 2049, counted
/// from 1 January 1984), ms = (h & FFFFFFFFh) mod 86 400 000. Never {0, 0}, which would mean
/// "do not verify" (CiA 302-2 §3.5 a).
ConfigurationStamp configuration_stamp(std::span<const std::uint8_t> concise_dcf);

/// The consumer time for a producer time (both ms): 2 x producer + 100 ms, so that one lost
/// heartbeat (a disturbed frame) is no heartbeat event, with margin for bus load and
/// scheduling; at most FFFFh; 0 (no heartbeat) gives 0.
std::uint16_t heartbeat_consumer_time_ms(std::uint16_t producer_ms);

/// The master's dictionary for `nodes` by the rules above, as a DCF with CANopenManager=1 (so
/// that it can be written out and read back as a master DCF). Nodes without a DCF get 1F81h and
/// 1F26h/1F27h only. Nodes with a program get what set_expected_program gives.
DeviceDescription derive_master(std::span<const NetworkNode> nodes);

// --- the application program (DSP 302 §9) --------------------------------------------------------
// The standard objects say what the master checks: 1F81h bit 5 (verify the application software
// version, DSP 302 §5.2 Table 23), bit 6 (automatic software update allowed, Table 24) and
// 1F53h/1F54h sub X (the expected date and time, as 1F52h sub 1/2 of the slave report them).
// CiA 306-3 has no key for the image itself; ours are NodeXProgramFile= and NodeXProgramVersion=
// in [Topology] (see the top), and --program/--program-version of cfgmgr push and master. A node
// with a version gets bit 5 and 1F53h/1F54h; with an image too, bit 6. This holds for a derived
// master and for a master DCF the project file names: there the description's programs replace
// the DCF's own 1F53h/1F54h sub X. A master DCF given alone says 1F53h/1F54h and bits 5/6 itself;
// the images then come from --program.
// load_network reports the keys' own errors (an image that cannot be read or is empty, a version
// that does not parse) at their lines; check_programs the rest.

/// Writes `program` into `master`: 1F53h/1F54h sub `node` = its version, 1F81h sub `node` |=
/// bit 5, and bit 6 when it has an image. Adds 1F53h/1F54h (sub 0..127) when `master` has
/// none. A program without a version changes nothing.
void set_expected_program(DeviceDescription& master, NodeId node, const NodeProgram& program);

/// Sets node `node`'s program and the master's objects for it, as a command line overriding the
/// description does: `file` (read now; empty: keep the description's image), `version`
/// (nullopt: keep the description's). Fails with a message naming the file when it cannot be
/// read or is empty, or when the node is not in the network.
Result<void> set_node_program(Network& network, NodeId node, const std::string& file,
                              std::optional<ProgramVersion> version);

/// The version the master expects node `node` to report in 1F52h: its 1F53h/1F54h sub `node`
/// when 1F81h sub `node` has bit 5; nullopt when the master does not check the node's version
/// (or both are 0, status G's case).
std::optional<ProgramVersion> expected_program_version(const Network& network, NodeId node);
/// CiA 302-3: the software identification the master expects node `node` to report in 1F56h
/// sub 1, its 1F55h sub `node` when 1F81h sub `node` has bit 5; nullopt when not checked or 0.
/// When set, the master checks it instead of expected_program_version.
std::optional<std::uint32_t> expected_software_identification(const Network& network, NodeId node);

/// The image at `file`: fails ("cannot open the file: ...", "the file is empty: ...") without
/// the path in the message, like read_file.
Result<std::vector<std::uint8_t>> read_program_image(const std::string& file);

/// What `cfgmgr check` (and push, master, build, verify on loading) say about the programs of a
/// loaded network, at the line that names them (the master DCF's for its own entries): an
/// image without a version (the master would have nothing to compare 1F52h with, error); 1F81h
/// bit 5 for a node whose 1F53h and 1F54h are both 0 or absent (status G at boot, CiA 302-2
/// Table 1, error); an image whose version trailer differs from the expected version (a
/// simulated device reports the trailer's version, so the update would end with status I,
/// warning); bit 6 without an image (status H when the version differs, warning).
void check_programs(const Network& network, Diagnostics& diagnostics);

}  // namespace cfg
