// python-can compatible UDP multicast bus. Facts about the peer come from python-can 4.1's
// can/interfaces/udp_multicast/{bus,utils}.py and can/message.py (Message._check).
#include "nmt/udp_bus.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <msgpack.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <utility>

#include "cfg/hex.hpp"
#include "kernel_time.hpp"

namespace nmt {

namespace {

constexpr std::string_view kUrlForm =
    "expected udp://GROUP:PORT[?iface=ADDR&ttl=N] with an IPv4 multicast GROUP, e.g. "
    "udp://239.74.163.2:43113";
const UdpBusOptions kDefaults{};
using detail::to_timespec;

// python-can receives with a 4096-byte buffer (GeneralPurposeUdpMulticastBus.max_buffer);
// anything longer is not a frame it could have sent.
constexpr std::size_t kMaxDatagram = 4096;

cfg::Error url_error(std::string_view url, std::string_view reason) {
  return cfg::Error{"bad bus URL '" + std::string(url) + "': " + std::string(reason) + "; " +
                    std::string(kUrlForm)};
}

std::optional<std::uint32_t> parse_ipv4(std::string_view text) {
  std::string s(text);
  in_addr a{};
  if (inet_pton(AF_INET, s.c_str(), &a) != 1) return std::nullopt;
  return a.s_addr;
}

std::string ipv4_text(std::uint32_t address_be) {
  in_addr a{};
  a.s_addr = address_be;
  std::array<char, INET_ADDRSTRLEN> buf{};
  inet_ntop(AF_INET, &a, buf.data(), buf.size());
  return buf.data();
}

template <class T>
std::optional<T> parse_decimal(std::string_view text) {
  T value{};
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc{} || end != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

std::string errno_text(int error) {
  return std::strerror(error);
}

// Owns a file descriptor while UdpBus::open() sets the sockets up.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

// ---- MessagePack encoding (msgpack-c) -------------------------------------------------------

int append_to_vector(void* data, const char* buf, std::size_t len) {
  auto* out = static_cast<std::vector<std::uint8_t>*>(data);
  out->insert(out->end(), reinterpret_cast<const std::uint8_t*>(buf),
              reinterpret_cast<const std::uint8_t*>(buf) + len);
  return 0;
}

void pack_key(msgpack_packer& pk, std::string_view key) {
  msgpack_pack_str(&pk, key.size());
  msgpack_pack_str_body(&pk, key.data(), key.size());
}

void pack_bool(msgpack_packer& pk, bool value) {
  if (value) {
    msgpack_pack_true(&pk);
  } else {
    msgpack_pack_false(&pk);
  }
}

// ---- MessagePack decoding (msgpack-c) -------------------------------------------------------

// msgpack-c allocates a container's element array as soon as it reads the header, before it
// knows whether the elements follow: a 5-byte datagram (array32 of 2^32-1) would make it ask
// for 64 GiB. Every element takes at least one byte, so a header announcing more elements than
// bytes remain is malformed; this walk rejects such input before msgpack-c sees it. It only
// skips over tokens (sizes from the MessagePack spec's format table); msgpack-c does the parsing.
bool container_sizes_fit(std::span<const std::uint8_t> d) {
  std::size_t i = 0;
  auto read_be = [&](std::size_t n) -> std::optional<std::uint64_t> {
    if (d.size() - i < n) return std::nullopt;
    std::uint64_t v = 0;
    for (std::size_t k = 0; k < n; ++k) v = v << 8 | d[i + k];
    i += n;
    return v;
  };
  while (i < d.size()) {
    const std::uint8_t b = d[i++];
    std::uint64_t skip = 0;                // payload bytes after the header
    std::uint64_t elements = 0;            // container elements announced by the header
    if (b <= 0x7f || b >= 0xe0) continue;  // positive / negative fixint
    if ((b & 0xf0) == 0x80) {
      elements = 2u * (b & 0x0fu);  // fixmap: keys and values
    } else if ((b & 0xf0) == 0x90) {
      elements = b & 0x0fu;  // fixarray
    } else if ((b & 0xe0) == 0xa0) {
      skip = b & 0x1fu;  // fixstr
    } else {
      std::optional<std::uint64_t> n;
      // One MessagePack format per line, as in the spec's format table.
      // clang-format off
      switch (b) {
        case 0xc0: case 0xc2: case 0xc3: continue;  // nil, false, true
        case 0xc4: case 0xd9: n = read_be(1); skip = n.value_or(0); break;  // bin8, str8
        case 0xc5: case 0xda: n = read_be(2); skip = n.value_or(0); break;  // bin16, str16
        case 0xc6: case 0xdb: n = read_be(4); skip = n.value_or(0); break;  // bin32, str32
        case 0xc7: n = read_be(1); skip = n.value_or(0) + 1; break;  // ext8 (+ type byte)
        case 0xc8: n = read_be(2); skip = n.value_or(0) + 1; break;  // ext16
        case 0xc9: n = read_be(4); skip = n.value_or(0) + 1; break;  // ext32
        case 0xcc: case 0xd0: skip = 1; n = 0; break;                // (u)int8
        case 0xcd: case 0xd1: skip = 2; n = 0; break;                // (u)int16
        case 0xca: case 0xce: case 0xd2: skip = 4; n = 0; break;     // float32, (u)int32
        case 0xcb: case 0xcf: case 0xd3: skip = 8; n = 0; break;     // float64, (u)int64
        case 0xd4: skip = 2; n = 0; break;                           // fixext1 (+ type)
        case 0xd5: skip = 3; n = 0; break;                           // fixext2
        case 0xd6: skip = 5; n = 0; break;                           // fixext4
        case 0xd7: skip = 9; n = 0; break;                           // fixext8
        case 0xd8: skip = 17; n = 0; break;                          // fixext16
        case 0xdc: n = read_be(2); elements = n.value_or(0); break;  // array16
        case 0xdd: n = read_be(4); elements = n.value_or(0); break;  // array32
        case 0xde: n = read_be(2); elements = 2 * n.value_or(0); break;  // map16
        case 0xdf: n = read_be(4); elements = 2 * n.value_or(0); break;  // map32
        default: return false;  // 0xc1 is never used
      }
      // clang-format on
      if (!n) return false;  // truncated header
    }
    if (elements > d.size() - i || skip > d.size() - i) return false;
    i += static_cast<std::size_t>(skip);
  }
  return true;
}

// Frees what msgpack_unpack_next() allocated.
struct Unpacked {
  msgpack_unpacked value;
  Unpacked() { msgpack_unpacked_init(&value); }
  ~Unpacked() { msgpack_unpacked_destroy(&value); }
  Unpacked(const Unpacked&) = delete;
  Unpacked& operator=(const Unpacked&) = delete;
};

// python-can builds can.Message(**map): a field is "true" when Python finds it truthy. We accept
// the types python-can's own packer produces (bool) and integers 0/1.
std::optional<bool> as_flag(const msgpack_object& o) {
  if (o.type == MSGPACK_OBJECT_BOOLEAN) return o.via.boolean;
  if (o.type == MSGPACK_OBJECT_POSITIVE_INTEGER && o.via.u64 <= 1) return o.via.u64 == 1;
  return std::nullopt;
}

}  // namespace

// ---- URL ---------------------------------------------------------------------------------------

cfg::Result<UdpBusOptions> parse_udp_url(std::string_view url) {
  constexpr std::string_view kScheme = "udp://";
  if (url.substr(0, kScheme.size()) != kScheme) return url_error(url, "not a udp:// URL");
  UdpBusOptions options;
  std::string_view rest = url.substr(kScheme.size());
  std::string_view query;
  if (auto q = rest.find('?'); q != std::string_view::npos) {
    query = rest.substr(q + 1);
    rest = rest.substr(0, q);
  }
  if (!rest.empty() && rest.back() == '/') rest.remove_suffix(1);
  if (!rest.empty() && rest.front() == '[') {
    return url_error(url, "IPv6 groups are not supported (IPv4 only)");
  }
  std::string_view group_text = rest;
  if (auto colon = rest.find(':'); colon != std::string_view::npos) {
    group_text = rest.substr(0, colon);
    auto port = parse_decimal<std::uint16_t>(rest.substr(colon + 1));
    if (!port || *port == 0) {
      return url_error(
          url, "port '" + std::string(rest.substr(colon + 1)) + "' is not a number in 1..65535");
    }
    options.port = *port;
  }
  if (!group_text.empty()) {
    auto group = parse_ipv4(group_text);
    if (!group) {
      return url_error(url, "group '" + std::string(group_text) + "' is not an IPv4 address");
    }
    // RFC 5771: IPv4 multicast is 224.0.0.0/4.
    if ((ntohl(*group) >> 28) != 0xE) {
      return url_error(url, "group '" + std::string(group_text) +
                                "' is not a multicast address (224.0.0.0 to 239.255.255.255)");
    }
    options.group = ipv4_text(*group);
  }
  while (!query.empty()) {
    auto amp = query.find('&');
    std::string_view item = query.substr(0, amp);
    query = amp == std::string_view::npos ? std::string_view{} : query.substr(amp + 1);
    auto eq = item.find('=');
    std::string_view key = item.substr(0, eq);
    std::string_view value =
        eq == std::string_view::npos ? std::string_view{} : item.substr(eq + 1);
    if (key == "iface") {
      auto address = parse_ipv4(value);
      if (!address) {
        return url_error(
            url, "iface '" + std::string(value) + "' is not the IPv4 address of a local interface");
      }
      options.interface_address = ipv4_text(*address);
    } else if (key == "ttl") {
      auto ttl = parse_decimal<unsigned>(value);
      if (!ttl || *ttl < 1 || *ttl > 255) {
        return url_error(url, "ttl '" + std::string(value) + "' is not a number in 1..255");
      }
      options.ttl = static_cast<std::uint8_t>(*ttl);
    } else {
      return url_error(url, "unknown option '" + std::string(key) + "' (known: iface, ttl)");
    }
  }
  return options;
}

std::string to_udp_url(const UdpBusOptions& options) {
  std::string url = "udp://" + options.group + ":" + std::to_string(options.port);
  char sep = '?';
  if (options.interface_address != kDefaults.interface_address) {
    url += sep + std::string("iface=") + options.interface_address;
    sep = '&';
  }
  if (options.ttl != kDefaults.ttl) url += sep + std::string("ttl=") + std::to_string(options.ttl);
  return url;
}

// ---- datagrams ---------------------------------------------------------------------------------

cfg::Result<std::vector<std::uint8_t>> encode_udp_datagram(const CanFrame& frame,
                                                           double timestamp_s) {
  // Mirror python-can's Message._check: a datagram it rejects would stop its receive thread.
  if (frame.dlc > 8) return cfg::Error{"CAN frame has dlc " + std::to_string(frame.dlc) + " > 8"};
  if (frame.rtr && frame.error) return cfg::Error{"a frame cannot be both remote and error"};
  const std::uint32_t max_id = frame.extended ? CanFrame::kMaxExtendedId : CanFrame::kMaxStandardId;
  if (frame.id > max_id) {
    return cfg::Error{"CAN id " + cfg::hex(frame.id) + " is out of range for " +
                      (frame.extended ? "a 29" : "an 11") + "-bit id"};
  }
  if (!std::isfinite(timestamp_s) || timestamp_s < 0) timestamp_s = 0;

  std::vector<std::uint8_t> out;
  out.reserve(160);
  msgpack_packer pk;
  msgpack_packer_init(&pk, &out, append_to_vector);
  // The keys and their order are python-can's pack_message(); values follow can.Message.
  msgpack_pack_map(&pk, 11);
  pack_key(pk, "timestamp");
  msgpack_pack_double(&pk, timestamp_s);
  pack_key(pk, "arbitration_id");
  msgpack_pack_uint32(&pk, frame.id);
  pack_key(pk, "is_extended_id");
  pack_bool(pk, frame.extended);
  pack_key(pk, "is_remote_frame");
  pack_bool(pk, frame.rtr);
  pack_key(pk, "is_error_frame");
  pack_bool(pk, frame.error);
  pack_key(pk, "channel");
  msgpack_pack_nil(&pk);
  // For a remote frame dlc is the requested length and data stays empty (Message._check:
  // "remote frames may not carry any data"); otherwise dlc equals len(data).
  pack_key(pk, "dlc");
  msgpack_pack_uint8(&pk, frame.dlc);
  pack_key(pk, "data");
  const std::size_t n = frame.rtr ? 0 : frame.dlc;
  msgpack_pack_bin(&pk, n);
  msgpack_pack_bin_body(&pk, frame.data.data(), n);
  pack_key(pk, "is_fd");
  pack_bool(pk, false);
  pack_key(pk, "bitrate_switch");
  pack_bool(pk, false);
  pack_key(pk, "error_state_indicator");
  pack_bool(pk, false);
  return out;
}

cfg::Result<CanFrame> decode_udp_datagram(std::span<const std::uint8_t> datagram) {
  if (datagram.empty()) return cfg::Error{"empty datagram"};
  if (!container_sizes_fit(datagram)) {
    return cfg::Error{"not MessagePack (truncated, or a container larger than the datagram)"};
  }
  Unpacked unpacked;
  std::size_t offset = 0;
  auto rc = msgpack_unpack_next(&unpacked.value, reinterpret_cast<const char*>(datagram.data()),
                                datagram.size(), &offset);
  if (rc != MSGPACK_UNPACK_SUCCESS) return cfg::Error{"not MessagePack"};
  if (offset != datagram.size()) return cfg::Error{"trailing bytes after the MessagePack map"};
  const msgpack_object& root = unpacked.value.data;
  if (root.type != MSGPACK_OBJECT_MAP) return cfg::Error{"not a MessagePack map"};

  // Defaults are can.Message.__init__'s.
  std::uint64_t id = 0;
  bool extended = true, remote = false, error = false, fd = false, brs = false, esi = false;
  std::optional<std::uint64_t> dlc;
  std::span<const std::uint8_t> data;
  for (std::uint32_t k = 0; k < root.via.map.size; ++k) {
    const msgpack_object& key_object = root.via.map.ptr[k].key;
    const msgpack_object& v = root.via.map.ptr[k].val;
    if (key_object.type != MSGPACK_OBJECT_STR) return cfg::Error{"a map key is not a string"};
    const std::string_view key(key_object.via.str.ptr, key_object.via.str.size);
    auto flag = [&](bool& out) -> cfg::Status {
      auto f = as_flag(v);
      if (!f) return cfg::Error{"'" + std::string(key) + "' is not a boolean"};
      out = *f;
      return {};
    };
    cfg::Status st;
    if (key == "arbitration_id") {
      if (v.type != MSGPACK_OBJECT_POSITIVE_INTEGER) {
        return cfg::Error{"'arbitration_id' is not a non-negative integer"};
      }
      id = v.via.u64;
    } else if (key == "dlc") {
      if (v.type == MSGPACK_OBJECT_POSITIVE_INTEGER) {
        dlc = v.via.u64;
      } else if (v.type != MSGPACK_OBJECT_NIL) {
        return cfg::Error{"'dlc' is not a non-negative integer"};
      }
    } else if (key == "data") {
      // bin from python-can (use_bin_type=True); raw str from packers without bin support.
      if (v.type == MSGPACK_OBJECT_BIN) {
        data = {reinterpret_cast<const std::uint8_t*>(v.via.bin.ptr), v.via.bin.size};
      } else if (v.type == MSGPACK_OBJECT_STR) {
        data = {reinterpret_cast<const std::uint8_t*>(v.via.str.ptr), v.via.str.size};
      } else if (v.type != MSGPACK_OBJECT_NIL) {
        return cfg::Error{"'data' is not binary"};
      }
    } else if (key == "is_extended_id") {
      st = flag(extended);
    } else if (key == "is_remote_frame") {
      st = flag(remote);
    } else if (key == "is_error_frame") {
      st = flag(error);
    } else if (key == "is_fd") {
      st = flag(fd);
    } else if (key == "bitrate_switch") {
      st = flag(brs);
    } else if (key == "error_state_indicator") {
      st = flag(esi);
    }
    // Other keys (timestamp, channel, anything a newer peer adds) do not change the frame.
    if (!st) return st.error();
  }

  // No CAN FD here; then the checks of python-can's Message._check.
  if (fd) return cfg::Error{"CAN FD frame (not supported)"};
  if (remote && error) return cfg::Error{"frame is both remote and error"};
  if (id > (extended ? CanFrame::kMaxExtendedId : CanFrame::kMaxStandardId)) {
    return cfg::Error{"arbitration_id " + std::to_string(id) + " out of range for " +
                      (extended ? "a 29" : "an 11") + "-bit id"};
  }
  if (remote) data = {};  // can.Message drops the data of a remote frame
  const std::uint64_t length = dlc.value_or(data.size());
  if (length > 8) return cfg::Error{"dlc " + std::to_string(length) + " > 8"};
  if (!remote && length != data.size()) {
    return cfg::Error{"dlc " + std::to_string(length) + " does not match " +
                      std::to_string(data.size()) + " data bytes"};
  }
  if (brs || esi) return cfg::Error{"bitrate_switch/error_state_indicator set on a classic frame"};

  CanFrame frame;
  frame.id = static_cast<std::uint32_t>(id);
  frame.extended = extended || error;  // error frames: as SocketCanBus reports them
  frame.rtr = remote;
  frame.error = error;
  frame.dlc = static_cast<std::uint8_t>(length);
  std::copy(data.begin(), data.end(), frame.data.begin());
  return frame;
}

// ---- the bus -----------------------------------------------------------------------------------

UdpBus::UdpBus(UdpBusOptions options, int receive_fd, int send_fd)
    : options_(std::move(options)), receive_fd_(receive_fd), send_fd_(send_fd) {}

UdpBus::~UdpBus() {
  ::close(receive_fd_);
  ::close(send_fd_);
}

cfg::Result<std::unique_ptr<UdpBus>> UdpBus::open(const UdpBusOptions& options) {
  const std::string where = to_udp_url(options);
  auto fail = [&](std::string_view what, int error) {
    return cfg::Error{where + ": " + std::string(what) + ": " + errno_text(error)};
  };
  auto group = parse_ipv4(options.group);
  if (!group || (ntohl(*group) >> 28) != 0xE) {
    return cfg::Error{where + ": group '" + options.group + "' is not an IPv4 multicast address"};
  }
  auto iface = parse_ipv4(options.interface_address);
  if (!iface) {
    return cfg::Error{where + ": iface '" + options.interface_address + "' is not an IPv4 address"};
  }
  if (options.port == 0 || options.ttl == 0) {
    return cfg::Error{where + ": port and ttl must be > 0"};
  }

  // Receive socket. python-can binds its own socket to the port with SO_REUSEADDR, so we do the
  // same (plus SO_REUSEPORT) to share the port with it and with other members on this host.
  Fd rx(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  if (rx.get() < 0) return fail("cannot create a UDP socket", errno);
  const int one = 1;
  if (setsockopt(rx.get(), SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0 ||
      setsockopt(rx.get(), SOL_SOCKET, SO_REUSEPORT, &one, sizeof one) != 0) {
    return fail("cannot share the port (SO_REUSEADDR/SO_REUSEPORT)", errno);
  }
  // A bigger buffer rides out bursts (an SDO block transfer is 127 frames back to back). The
  // kernel silently caps the request at net.core.rmem_max, which is fine.
  (void)setsockopt(rx.get(), SOL_SOCKET, SO_RCVBUF, &options.receive_buffer_bytes,
                   sizeof options.receive_buffer_bytes);
  // SO_TIMESTAMPNS (socket(7)): the kernel's receive time comes with each datagram, so a datagram
  // that waited in the socket while the process was stopped keeps the time it arrived (issue 22).
  if (setsockopt(rx.get(), SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof one) != 0) {
    return fail("cannot enable receive timestamps (SO_TIMESTAMPNS)", errno);
  }
  // Binding to the group address (not INADDR_ANY) makes the kernel deliver only datagrams sent
  // to this group, so groups sharing a port stay apart for us.
  sockaddr_in bind_address{};
  bind_address.sin_family = AF_INET;
  bind_address.sin_port = htons(options.port);
  bind_address.sin_addr.s_addr = *group;
  if (::bind(rx.get(), reinterpret_cast<const sockaddr*>(&bind_address), sizeof bind_address) !=
      0) {
    return fail("cannot bind to the group's port", errno);
  }
  ip_mreq membership{};
  membership.imr_multiaddr.s_addr = *group;
  membership.imr_interface.s_addr = *iface;
  if (setsockopt(rx.get(), IPPROTO_IP, IP_ADD_MEMBERSHIP, &membership, sizeof membership) != 0) {
    const int error = errno;
    if (error == ENODEV || error == EADDRNOTAVAIL) {
      return cfg::Error{where + ": cannot join the group on " + options.interface_address +
                        " (not the address of a local interface?): " + errno_text(error)};
    }
    return fail("cannot join the group", error);
  }

  // Send socket, separate so its ephemeral port tells our looped-back datagrams apart.
  Fd tx(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  if (tx.get() < 0) return fail("cannot create a UDP socket", errno);
  in_addr out_interface{};
  out_interface.s_addr = *iface;
  const int ttl = options.ttl;
  if (setsockopt(tx.get(), IPPROTO_IP, IP_MULTICAST_IF, &out_interface, sizeof out_interface) !=
      0) {
    return fail("cannot send on " + options.interface_address + " (IP_MULTICAST_IF)", errno);
  }
  if (setsockopt(tx.get(), IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl) != 0 ||
      setsockopt(tx.get(), IPPROTO_IP, IP_MULTICAST_LOOP, &one, sizeof one) != 0) {
    return fail("cannot set multicast TTL/loopback", errno);
  }
  sockaddr_in local{};
  local.sin_family = AF_INET;
  local.sin_addr.s_addr = *iface;
  if (::bind(tx.get(), reinterpret_cast<const sockaddr*>(&local), sizeof local) != 0) {
    return fail("cannot bind the send socket to " + options.interface_address, errno);
  }
  socklen_t local_size = sizeof local;
  if (getsockname(tx.get(), reinterpret_cast<sockaddr*>(&local), &local_size) != 0) {
    return fail("cannot read the send socket's address", errno);
  }

  auto bus = std::unique_ptr<UdpBus>(new UdpBus(options, rx.release(), tx.release()));
  bus->options_.group = ipv4_text(*group);
  bus->options_.interface_address = ipv4_text(*iface);
  bus->group_be_ = *group;
  bus->own_address_be_ = local.sin_addr.s_addr;
  bus->own_port_be_ = local.sin_port;
  return bus;
}

SendResult UdpBus::try_send(const CanFrame& frame) {
  using Status = SendResult::Status;
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  // python-can stamps with time.time(): seconds since the Unix epoch as a float.
  const double timestamp_s = std::chrono::duration<double>(now).count();
  auto datagram = encode_udp_datagram(frame, timestamp_s);
  if (!datagram) {
    return {Status::Refused,
            url() + ": cannot send " + to_candump(frame) + ": " + datagram.error().message};
  }
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(options_.port);
  to.sin_addr.s_addr = group_be_;
  for (;;) {
    const ssize_t n =
        ::sendto(send_fd_, datagram->data(), datagram->size(), MSG_DONTWAIT | MSG_NOSIGNAL,
                 reinterpret_cast<const sockaddr*>(&to), sizeof to);
    if (n == static_cast<ssize_t>(datagram->size())) return {};
    if (n >= 0) return {Status::Failed, url() + ": short send of " + to_candump(frame)};
    const int error = errno;
    if (error == EINTR) continue;
    return {send_status_of_errno(error),
            url() + ": cannot send " + to_candump(frame) + ": " + errno_text(error)};
  }
}

cfg::Status UdpBus::send(const CanFrame& frame) {
  const auto deadline = std::chrono::steady_clock::now() + options_.send_timeout;
  for (;;) {
    auto attempt = try_send(frame);
    if (attempt.status == SendResult::Status::Sent) return {};
    if (attempt.status != SendResult::Status::QueueFull) return cfg::Error{attempt.message};
    // Buffer full: wait for room, but never past the deadline. ENOBUFS does not wake poll(), so
    // wait at most 10 ms at a time and retry.
    ++counters_.send_waits;
    const auto left =
        std::chrono::duration_cast<Duration>(deadline - std::chrono::steady_clock::now());
    if (left <= Duration::zero()) {
      return cfg::Error{url() + ": cannot send " + to_candump(frame) + ": send buffer full for " +
                        std::to_string(options_.send_timeout.count() / 1000) + " ms"};
    }
    pollfd p{send_fd_, POLLOUT, 0};
    const timespec wait = to_timespec(std::min<Duration>(left, std::chrono::milliseconds(10)));
    (void)::ppoll(&p, 1, &wait, nullptr);
  }
}

cfg::Result<std::optional<ReceivedFrame>> UdpBus::receive(Duration timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::array<std::uint8_t, kMaxDatagram> buffer;
  for (;;) {
    sockaddr_in from{};
    // recvmsg for the receive time (SO_TIMESTAMPNS, a control message). MSG_TRUNC: the return
    // value is the datagram's real length even when it did not fit.
    iovec iov{buffer.data(), buffer.size()};
    alignas(cmsghdr) std::array<char, CMSG_SPACE(sizeof(timespec))> control{};
    msghdr msg{};
    msg.msg_name = &from;
    msg.msg_namelen = sizeof from;
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control.data();
    msg.msg_controllen = control.size();
    const ssize_t n = ::recvmsg(receive_fd_, &msg, MSG_DONTWAIT | MSG_TRUNC);
    if (n >= 0) {
      TimePoint received_at = wall_clock_now();  // without a stamp: as old as now
      for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_TIMESTAMPNS) {
          timespec ts{};
          std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
          received_at = detail::from_timespec(ts);
        }
      }
      if (from.sin_port == own_port_be_ && from.sin_addr.s_addr == own_address_be_) {
        ++counters_.own_datagrams;  // IP_MULTICAST_LOOP hands every member its own datagrams
        continue;
      }
      if (static_cast<std::size_t>(n) > buffer.size()) {
        ++counters_.rejected;
        last_rejection_ = "datagram of " + std::to_string(n) + " bytes is longer than " +
                          std::to_string(kMaxDatagram);
        continue;
      }
      auto frame = decode_udp_datagram({buffer.data(), static_cast<std::size_t>(n)});
      if (!frame) {
        ++counters_.rejected;
        last_rejection_ = frame.error().message;
        continue;
      }
      return std::optional<ReceivedFrame>(ReceivedFrame{*frame, received_at, StampClock::Realtime});
    }
    const int error = errno;
    if (error == EINTR) continue;
    if (error != EAGAIN && error != EWOULDBLOCK) {
      return cfg::Error{url() + ": receive failed: " + errno_text(error)};
    }
    const auto left =
        std::chrono::duration_cast<Duration>(deadline - std::chrono::steady_clock::now());
    if (left <= Duration::zero()) return std::optional<ReceivedFrame>{};
    pollfd p{receive_fd_, POLLIN, 0};
    const timespec wait = to_timespec(left);
    if (::ppoll(&p, 1, &wait, nullptr) < 0 && errno != EINTR) {
      return cfg::Error{url() + ": waiting for a frame failed: " + errno_text(errno)};
    }
  }
}

std::string UdpBus::url() const {
  return to_udp_url(options_);
}

cfg::Result<std::unique_ptr<Bus>> open_udp_bus(std::string_view url) {
  auto options = parse_udp_url(url);
  if (!options) return options.error();
  auto bus = UdpBus::open(*options);
  if (!bus) return bus.error();
  return std::unique_ptr<Bus>(std::move(*bus));
}

}  // namespace nmt
