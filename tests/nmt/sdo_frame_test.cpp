// The SDO frame codec against frames written out by hand from the SDO protocols of CiA 301
// §7.2.4.3 (command specifier in bits 7..5 of byte 0, multiplexer little-endian in bytes 1..3).
// Block CRCs are CRC-16/XMODEM values from Python's binascii.crc_hqx(data, 0).
#include <gtest/gtest.h>

#include <string>
#include <variant>

#include "nmt/sdo/sdo_frame.hpp"

namespace nmt::sdo {
namespace {

Payload payload(std::string_view candump) {
  auto f = from_candump(candump);
  EXPECT_TRUE(f.has_value()) << candump;
  auto p = f ? sdo_payload(*f) : std::nullopt;
  EXPECT_TRUE(p.has_value()) << candump;
  return p.value_or(Payload{});
}
std::string text(std::uint32_t id, const Payload& p) {
  return to_candump(CanFrame::make(id, p));
}
template <class T>
T client(std::string_view candump) {
  auto f = parse_client_frame(payload(candump));
  EXPECT_TRUE(f && std::holds_alternative<T>(*f)) << candump;
  return f && std::holds_alternative<T>(*f) ? std::get<T>(*f) : T{};
}
template <class T>
T server(std::string_view candump) {
  auto f = parse_server_frame(payload(candump));
  EXPECT_TRUE(f && std::holds_alternative<T>(*f)) << candump;
  return f && std::holds_alternative<T>(*f) ? std::get<T>(*f) : T{};
}

TEST(SdoFrame, ExpeditedDownloadOfTwoBytes) {
  // ccs=1, n=2, e=1, s=1: 2Bh; 1017h sub 0; 1000 = 03E8h little-endian.
  const auto f = client<InitiateDownloadRequest>("605#2B171000E8030000");
  EXPECT_EQ(f.address, (cfg::ObjectAddress{0x1017, 0}));
  EXPECT_TRUE(f.expedited);
  EXPECT_EQ(f.size, 2u);
  EXPECT_EQ(f.data, (std::array<std::uint8_t, 4>{0xE8, 0x03, 0, 0}));
  EXPECT_EQ(text(0x605, encode(f)), "605#2B171000E8030000");
}

TEST(SdoFrame, ExpeditedWithoutSizeCarriesFourBytes) {
  // e=1, s=0 (22h): n is not used, the size is not indicated.
  const auto f = client<InitiateDownloadRequest>("605#2E171000E8030000");
  EXPECT_TRUE(f.expedited);
  EXPECT_EQ(f.size, std::nullopt);
  EXPECT_EQ(text(0x605, encode(f)), "605#22171000E8030000");  // the unused n encodes as 0
}

TEST(SdoFrame, SegmentedInitiateCarriesTheSize) {
  // e=0, s=1 (21h): bytes 4..7 hold the size, 12 bytes.
  const auto f = client<InitiateDownloadRequest>("605#210520000C000000");
  EXPECT_FALSE(f.expedited);
  EXPECT_EQ(f.size, 12u);
  EXPECT_EQ(f.address, (cfg::ObjectAddress{0x2005, 0}));
}

TEST(SdoFrame, UploadResponses) {
  // scs=2, n=0, e=1, s=1 (43h): four bytes 00020191h... of 1000h.
  const auto e = server<InitiateUploadResponse>("585#4300100091010200");
  EXPECT_TRUE(e.expedited);
  EXPECT_EQ(e.size, 4u);
  EXPECT_EQ(e.data, (std::array<std::uint8_t, 4>{0x91, 0x01, 0x02, 0x00}));
  // 41h: segmented, 20 bytes follow.
  const auto s = server<InitiateUploadResponse>("585#4108100014000000");
  EXPECT_FALSE(s.expedited);
  EXPECT_EQ(s.size, 20u);
  EXPECT_EQ(client<InitiateUploadRequest>("605#4008100000000000").address,
            (cfg::ObjectAddress{0x1008, 0}));
  EXPECT_EQ(server<InitiateDownloadResponse>("585#6017100000000000").address,
            (cfg::ObjectAddress{0x1017, 0}));
}

TEST(SdoFrame, SegmentsCarryToggleSizeAndLast) {
  // ccs=0, t=0, n=0, c=0: seven bytes "Hello w".
  const auto a = client<DownloadSegmentRequest>("605#0048656C6C6F2077");
  EXPECT_FALSE(a.toggle);
  EXPECT_FALSE(a.last);
  EXPECT_EQ(a.size, 7);
  // 15h: t=1, n=2, c=1: five bytes "orld!".
  const auto b = client<DownloadSegmentRequest>("605#156F726C64210000");
  EXPECT_TRUE(b.toggle);
  EXPECT_TRUE(b.last);
  EXPECT_EQ(b.size, 5);
  EXPECT_EQ(text(0x605, encode(b)), "605#156F726C64210000");
  // The responses and requests that carry only t: 20h / 30h (scs=1), 60h / 70h (ccs=3).
  EXPECT_FALSE(server<DownloadSegmentResponse>("585#2000000000000000").toggle);
  EXPECT_TRUE(server<DownloadSegmentResponse>("585#3000000000000000").toggle);
  EXPECT_TRUE(client<UploadSegmentRequest>("605#7000000000000000").toggle);
  // 0Dh from the server: t=0, n=6, c=1: one byte.
  const auto c = server<UploadSegmentResponse>("585#0D41000000000000");
  EXPECT_EQ(c.size, 1);
  EXPECT_TRUE(c.last);
}

TEST(SdoFrame, AbortCarriesMultiplexerAndCode) {
  // cs=4 (80h); 1018h sub 09h; 0609 0011 "sub-index does not exist".
  const auto a = server<Abort>("585#8018100911000906");
  EXPECT_EQ(a.address, (cfg::ObjectAddress{0x1018, 9}));
  EXPECT_EQ(a.code, SdoAbort::SubIndexDoesNotExist);
  EXPECT_EQ(text(0x585, encode(a)), "585#8018100911000906");
  EXPECT_EQ(client<Abort>("605#8017100000000405").code, SdoAbort::Timeout);  // 0504 0000
}

TEST(SdoFrame, BlockDownloadFrames) {
  // ccs=6, cc=1, s=1, cs=0 (C6h); 10 bytes to 2000h.
  const auto init = client<BlockDownloadInitiateRequest>("605#C60020000A000000");
  EXPECT_EQ(init.address, (cfg::ObjectAddress{0x2000, 0}));
  EXPECT_TRUE(init.crc);
  EXPECT_EQ(init.size, 10u);
  // scs=5, sc=1, ss=0 (A4h), blksize 127.
  const auto response = server<BlockDownloadInitiateResponse>("585#A40020007F000000");
  EXPECT_TRUE(response.crc);
  EXPECT_EQ(response.block_size, 127);
  // scs=5, ss=2 (A2h): ackseq 2, blksize 127.
  EXPECT_EQ(server<BlockDownloadAck>("585#A2027F0000000000"), (BlockDownloadAck{2, 127}));
  // ccs=6, n=4, cs=1 (D1h); CRC of 01..0A is CD4Bh.
  EXPECT_EQ(client<BlockDownloadEndRequest>("605#D14BCD0000000000"),
            (BlockDownloadEndRequest{4, 0xCD4B}));
  server<BlockDownloadEndResponse>("585#A100000000000000");
  // ss=3 is not defined.
  EXPECT_FALSE(parse_server_frame(payload("585#A300000000000000")).has_value());
}

TEST(SdoFrame, BlockUploadFrames) {
  // ccs=5, cc=1, cs=0 (A4h); blksize 127, pst 0.
  const auto init = client<BlockUploadInitiateRequest>("605#A40810007F000000");
  EXPECT_EQ(init.address, (cfg::ObjectAddress{0x1008, 0}));
  EXPECT_TRUE(init.crc);
  EXPECT_EQ(init.block_size, 127);
  EXPECT_EQ(init.protocol_switch_threshold, 0);
  // scs=6, sc=1, s=1, ss=0 (C6h): 20 bytes.
  const auto response = server<BlockUploadInitiateResponse>("585#C608100014000000");
  EXPECT_TRUE(response.crc);
  EXPECT_EQ(response.size, 20u);
  client<BlockUploadStart>("605#A300000000000000");
  EXPECT_EQ(client<BlockUploadAck>("605#A2037F0000000000"), (BlockUploadAck{3, 127}));
  // scs=6, n=1, ss=1 (C5h); CRC of "CANopen test device!" is 8D1Dh.
  EXPECT_EQ(server<BlockUploadEndRequest>("585#C51D8D0000000000"),
            (BlockUploadEndRequest{1, 0x8D1D}));
  client<BlockUploadEndResponse>("605#A100000000000000");
}

TEST(SdoFrame, SubBlockFramesAreSegmentsExceptAnAbort) {
  // c=1, seqno 2 (82h).
  const auto f = parse_sub_block_frame(payload("605#8208090A00000000"));
  ASSERT_TRUE(std::holds_alternative<BlockSegment>(f));
  EXPECT_TRUE(std::get<BlockSegment>(f).last);
  EXPECT_EQ(std::get<BlockSegment>(f).seq, 2);
  // 80h would be segment 0 with c=1: it is the abort (cs=4), here 0504 0003.
  const auto a = parse_sub_block_frame(payload("605#8000200003000405"));
  ASSERT_TRUE(std::holds_alternative<Abort>(a));
  EXPECT_EQ(std::get<Abort>(a).code, SdoAbort::InvalidSequenceNumber);
  // A segment numbered 0 without c stays a segment, for the receiver to refuse.
  EXPECT_EQ(std::get<BlockSegment>(parse_sub_block_frame(payload("605#0001020304050607"))).seq, 0);
}

TEST(SdoFrame, UndefinedCommandSpecifiersDoNotParse) {
  EXPECT_FALSE(parse_client_frame(payload("605#E000000000000000")).has_value());  // ccs 7
  EXPECT_FALSE(parse_server_frame(payload("585#E000000000000000")).has_value());  // scs 7
}

TEST(SdoFrame, ShortFramesReadAsZeroPaddedAndRemoteFramesAreNone) {
  EXPECT_EQ(payload("605#40001000"), (Payload{0x40, 0x00, 0x10, 0, 0, 0, 0, 0}));
  EXPECT_FALSE(sdo_payload(*from_candump("605#R")).has_value());
  EXPECT_FALSE(sdo_payload(*from_candump("605#")).has_value());
}

TEST(SdoFrame, TwentyNineBitChannels) {
  // CiA 301 COB-ID: bit 29 set = 29-bit identifier; bit 31 set = not valid.
  const auto extended = cfg::CobId::from_word(0x20000605);
  EXPECT_EQ(to_candump(make_frame(extended, Payload{0x40})), "00000605#4000000000000000");
  EXPECT_TRUE(on_channel(*from_candump("00000605#40"), extended));
  EXPECT_FALSE(on_channel(*from_candump("605#40"), extended));
  EXPECT_FALSE(on_channel(*from_candump("605#40"), cfg::CobId::from_word(0x80000605)));
}

TEST(SdoFrame, LastSegmentEmptyBytes) {
  // n of the end block frame: 10 bytes = 7 + 3, four bytes of the last segment empty.
  EXPECT_EQ(last_segment_empty_bytes(10), 4);
  EXPECT_EQ(last_segment_empty_bytes(14), 0);
  EXPECT_EQ(last_segment_empty_bytes(0), 7);  // an empty value is one empty segment
}

}  // namespace
}  // namespace nmt::sdo
