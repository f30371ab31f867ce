// The --report FILE.html of cfgmgr push and cfgmgr master: one self-contained page (inline SVG
// and CSS, nothing fetched, no script) that shows a run over bus time: a timeline per node (its
// boot steps, errors, retries and EMCYs), the bus load, and the result table. A pure function of
// ReportData; report_recorder.hpp makes the data from a run.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace cfgmgr::report {

/// What a node was doing over a stretch of bus time: the boot steps of CiA 302-2 §3 grouped as
/// a person reads them, and operational once it was started.
enum class PhaseKind : std::uint8_t {
  BootUp,        ///< waiting for the boot-up message after a reset (§3.2)
  Identify,      ///< 1000h/1018h uploads, NMT state and software checks (§3.4)
  Program,       ///< program download (DSP 302 §9: 1F50h/1F51h)
  Verify,        ///< 1020h upload (§3.5 b)
  Restore,       ///< 1011h 'load', reset, boot-up
  Download,      ///< configuration writes (§3.5 d)
  Save,          ///< 1020h, 1010h 'save'
  Application,   ///< the application's own configuration step
  ErrorControl,  ///< waiting for the first heartbeat (§4.1) before the start
  RetryWait,     ///< waiting for the next try of a mandatory slave (§3.3)
  Operational,   ///< the master knows the node operational (started)
};

/// A single moment on a node's timeline (or the bus's, or the master's).
enum class MarkKind : std::uint8_t {
  BootUp,      ///< a boot-up message seen
  Error,       ///< a boot error (CiA 302-2 Table 1), heartbeat or guarding lost
  Retry,       ///< a new try of boot NMT slave began (§3.3)
  Emergency,   ///< an EMCY (CiA 301 §7.2.7), or a flood's summary
  ErrorFrame,  ///< an error frame the controller reported
  Master,      ///< NMT start-up complete, halted, ... (drawn across every lane)
};

struct Phase {
  PhaseKind kind = PhaseKind::BootUp;
  double begin_s = 0;  ///< seconds of bus time since the start of the run
  double end_s = 0;
  std::string title;  ///< what a pointer over it shows ("download: 12 of 40 entries")
  /// Download: when each entry was written (seconds since the start).
  std::vector<double> entries_s;
};

struct Mark {
  MarkKind kind = MarkKind::Error;
  double at_s = 0;
  std::string title;
};

/// A node's line in the result table and its lane in the timeline.
struct NodeRow {
  std::uint8_t node_id = 0;
  std::string name;
  std::string result;  ///< "configured", "skipped", "error B", ...
  bool failed = false;
  bool mandatory = false;
  std::string message;  ///< the words of the result ("value of object 1000h differs ...")
  std::size_t entries = 0;
  std::uint64_t emergencies = 0;
  unsigned retries = 0;
  double seconds = 0;  ///< from the node's first boot step to its result
  std::vector<Phase> phases;
  std::vector<Mark> marks;
};

/// The bus load over one stretch: the bits of the frames that ended in it over what the bit
/// rate carries in it, 0..1.
struct LoadSample {
  double begin_s = 0;
  double end_s = 0;
  double load = 0;
};

struct ReportData {
  std::string tool;     ///< "push", "master"
  std::string network;  ///< the description as given
  std::string bus;      ///< the --bus URL
  bool ok = true;       ///< the run's outcome as its exit code says it
  std::string outcome;  ///< one line: "every node configured", "NMT start-up halted: ..."
  double duration_s = 0;
  std::uint64_t frames = 0;
  std::uint32_t bitrate_bps = 0;
  bool bitrate_assumed = false;  ///< not the bus's own: the load is an estimate
  std::vector<NodeRow> nodes;    ///< in node-ID order
  std::vector<LoadSample> load;
  std::vector<Mark> bus_marks;     ///< error frames
  std::vector<Mark> master_marks;  ///< the master's own events
};

/// The page. Every text of `data` is HTML-escaped; the page holds no script, no style sheet,
/// font or image from elsewhere and no URL. A node whose `failed` is set has class "failed" on
/// its lane (id "lane-N") and its table row (id "row-N"), and its result as the row's title.
std::string html_report(const ReportData& data);

/// `text` with &, <, >, " and ' as HTML character references.
std::string escape_html(std::string_view text);

}  // namespace cfgmgr::report
