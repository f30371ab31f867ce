// python-can's udp_multicast datagram (nmt/io/udp_datagram.hpp): one CAN frame as a MessagePack
// map, encoded and decoded with msgpack-c. Facts about the peer come from python-can 4.1's
// can/interfaces/udp_multicast/utils.py (pack_message, unpack_message) and can/message.py
// (Message._check).
#include "nmt/io/udp_datagram.hpp"

#include <msgpack.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <string_view>

#include "cfg/hex.hpp"

namespace nmt {

namespace {

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

}  // namespace nmt
