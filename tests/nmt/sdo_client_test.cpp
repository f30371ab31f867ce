// SDO client, frame by frame against scripted server responses. Frame bytes follow CiA 301
// §7.2.4.3 (public knowledge of CiA 301; not in spec/), written out by hand; block CRCs are
// CRC-16/XMODEM values from Python's binascii.crc_hqx(data, 0).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "nmt/sdo.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using Frames = std::vector<std::string>;
using Bytes = std::vector<std::uint8_t>;

class SdoClientTest : public ::testing::Test {
 protected:
  SdoClient client{SdoClientConfig::for_node(5)};
  TimePoint now{0};

  Frames tick(TimePoint t = TimePoint{0}) {
    if (t > now) now = t;
    std::vector<CanFrame> out;
    client.on_timer(now, out);
    return text(out);
  }
  Frames respond(std::string_view candump) {
    auto f = from_candump(candump);
    EXPECT_TRUE(f.has_value()) << candump;
    std::vector<CanFrame> out;
    EXPECT_TRUE(client.on_frame(*f, now, out));
    return text(out);
  }
  static Frames text(const std::vector<CanFrame>& frames) {
    Frames s;
    for (const auto& f : frames) s.push_back(to_candump(f));
    return s;
  }
  static SdoTransferOptions block() {
    SdoTransferOptions o;
    o.mode = SdoMode::Block;
    return o;
  }
};

TEST_F(SdoClientTest, ExpeditedDownload) {
  auto id = client.download(0x1017, 0, {0xE8, 0x03});
  EXPECT_EQ(client.next_deadline(), TimePoint{0});  // queued: start as soon as possible
  EXPECT_EQ(tick(), Frames{"605#2B171000E8030000"});
  EXPECT_EQ(client.result(id), nullptr);
  EXPECT_EQ(respond("585#6017100000000000"), Frames{});
  ASSERT_NE(client.result(id), nullptr);
  EXPECT_TRUE(client.result(id)->ok());
  EXPECT_EQ(client.result(id)->protocol, SdoProtocol::Expedited);
  EXPECT_FALSE(client.busy());
  EXPECT_EQ(client.next_deadline(), std::nullopt);
}

TEST_F(SdoClientTest, ExpeditedUpload) {
  auto id = client.upload(0x1000, 0);
  EXPECT_EQ(tick(), Frames{"605#4000100000000000"});
  EXPECT_EQ(respond("585#4300100091010200"), Frames{});
  auto r = client.take_result(id);
  ASSERT_TRUE(r.has_value());
  EXPECT_TRUE(r->ok());
  EXPECT_EQ(r->data, (Bytes{0x91, 0x01, 0x02, 0x00}));
  EXPECT_EQ(client.result(id), nullptr);  // taken
}

TEST_F(SdoClientTest, ExpeditedUploadWithoutSizeIndicatedTakesFourBytes) {
  auto id = client.upload(0x1000, 0);
  tick();
  respond("585#4200100091010200");  // e=1, s=0
  EXPECT_EQ(client.result(id)->data, (Bytes{0x91, 0x01, 0x02, 0x00}));
}

TEST_F(SdoClientTest, SegmentedUploadAlternatesTheToggleBit) {
  auto id = client.upload(0x1008, 0);
  EXPECT_EQ(tick(), Frames{"605#4008100000000000"});
  EXPECT_EQ(respond("585#4108100014000000"), Frames{"605#6000000000000000"});
  EXPECT_EQ(respond("585#0043414E6F70656E"), Frames{"605#7000000000000000"});
  EXPECT_EQ(respond("585#1020746573742064"), Frames{"605#6000000000000000"});
  EXPECT_EQ(respond("585#0365766963652100"), Frames{});
  const std::string text = "CANopen test device!";
  ASSERT_TRUE(client.result(id)->ok());
  EXPECT_EQ(client.result(id)->data, Bytes(text.begin(), text.end()));
  EXPECT_EQ(client.result(id)->protocol, SdoProtocol::Segmented);
}

TEST_F(SdoClientTest, SegmentedDownload) {
  const std::string text = "Hello world!";
  auto id = client.download(0x2005, 0, Bytes(text.begin(), text.end()));
  EXPECT_EQ(tick(), Frames{"605#210520000C000000"});
  EXPECT_EQ(respond("585#6005200000000000"), Frames{"605#0048656C6C6F2077"});
  EXPECT_EQ(respond("585#2000000000000000"), Frames{"605#156F726C64210000"});
  EXPECT_EQ(respond("585#3000000000000000"), Frames{});
  EXPECT_TRUE(client.result(id)->ok());
}

TEST_F(SdoClientTest, SegmentedModeSendsShortValuesSegmented) {
  SdoTransferOptions o;
  o.mode = SdoMode::Segmented;
  client.download(0x1017, 0, {0xE8, 0x03}, o);
  // s=1, size 2; then one segment: t=0, n=5, c=1 (0x0B).
  EXPECT_EQ(tick(), Frames{"605#2117100002000000"});
  EXPECT_EQ(respond("585#6017100000000000"), Frames{"605#0BE8030000000000"});
}

TEST_F(SdoClientTest, EmptyDownloadIsOneEmptySegment) {
  auto id = client.download(0x2005, 0, {});
  EXPECT_EQ(tick(), Frames{"605#2105200000000000"});
  // t=0, n=7, c=1: 0x0F.
  EXPECT_EQ(respond("585#6005200000000000"), Frames{"605#0F00000000000000"});
  respond("585#2000000000000000");
  EXPECT_TRUE(client.result(id)->ok());
}

TEST_F(SdoClientTest, ReportsServerAbortWithItsCode) {
  auto id = client.upload(0x1018, 9);
  tick();
  EXPECT_EQ(respond("585#8018100911000906"), Frames{});
  const auto* r = client.result(id);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->abort, SdoAbort::SubIndexDoesNotExist);
  EXPECT_TRUE(r->aborted_by_server);
  EXPECT_FALSE(r->ok());
}

TEST_F(SdoClientTest, ServerAbortWithCodeZeroIsNotSuccess) {
  auto id = client.upload(0x1000, 0);
  tick();
  respond("585#8000100000000000");
  EXPECT_EQ(client.result(id)->abort, SdoAbort::General);
}

TEST_F(SdoClientTest, SendsTimeoutAbortWhenTheServerDoesNotAnswer) {
  SdoTransferOptions o;
  o.timeout = 250ms;
  auto id = client.download(0x1017, 0, {0xE8, 0x03}, o);
  EXPECT_EQ(tick(TimePoint{1000}), Frames{"605#2B171000E8030000"});
  EXPECT_EQ(client.next_deadline(), TimePoint{251'000});
  EXPECT_EQ(tick(TimePoint{250'999}), Frames{});
  // 0504 0000, bytes 00 00 04 05.
  EXPECT_EQ(tick(TimePoint{251'000}), Frames{"605#8017100000000405"});
  EXPECT_EQ(client.result(id)->abort, SdoAbort::Timeout);
  EXPECT_FALSE(client.result(id)->aborted_by_server);
}

TEST_F(SdoClientTest, AbortsWhenServerToggleBitDoesNotAlternate) {
  auto id = client.upload(0x1008, 0);
  tick();
  respond("585#4108100014000000");
  respond("585#0043414E6F70656E");
  // The second segment should carry t=1.
  EXPECT_EQ(respond("585#0020746573742064"), Frames{"605#8008100000000305"});
  EXPECT_EQ(client.result(id)->abort, SdoAbort::ToggleBitNotAlternated);
}

TEST_F(SdoClientTest, AbortsWhenTheResponseNamesAnotherObject) {
  auto id = client.download(0x1017, 0, {0xE8, 0x03});
  tick();
  EXPECT_EQ(respond("585#6016100000000000"), Frames{"605#8017100000000008"});
  EXPECT_EQ(client.result(id)->abort, SdoAbort::General);
}

TEST_F(SdoClientTest, AbortsOnUnexpectedCommandSpecifier) {
  auto id = client.download(0x1017, 0, {0xE8, 0x03});
  tick();
  EXPECT_EQ(respond("585#4300100091010200"), Frames{"605#8017100001000405"});
  EXPECT_EQ(client.result(id)->abort, SdoAbort::InvalidCommandSpecifier);
}

TEST_F(SdoClientTest, UploadLongerThanIndicatedAbortsWithLengthMismatch) {
  auto id = client.upload(0x1008, 0);
  tick();
  respond("585#4108100008000000");  // 8 bytes announced
  respond("585#0043414E6F70656E");
  EXPECT_EQ(respond("585#1120746573742064"), Frames{"605#8008100010000706"});
  EXPECT_EQ(client.result(id)->abort, SdoAbort::LengthMismatch);
}

TEST_F(SdoClientTest, BlockDownloadFallsBackToSegmentedWhenServerRefusesBlock) {
  SdoTransferOptions o = block();
  auto id = client.download(0x2000, 0, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10}, o);
  EXPECT_EQ(tick(), Frames{"605#C60020000A000000"});
  // 0504 0001: the server does not know the block command; retry segmented.
  EXPECT_EQ(respond("585#8000200001000405"), Frames{"605#210020000A000000"});
  EXPECT_EQ(respond("585#6000200000000000"), Frames{"605#0001020304050607"});
  // t=1, n=4, c=1: 0x19.
  EXPECT_EQ(respond("585#2000000000000000"), Frames{"605#1908090A00000000"});
  EXPECT_EQ(respond("585#3000000000000000"), Frames{});
  const auto* r = client.result(id);
  ASSERT_TRUE(r->ok());
  EXPECT_TRUE(r->fell_back);
  EXPECT_EQ(r->protocol, SdoProtocol::Segmented);
}

TEST_F(SdoClientTest, BlockUploadFallsBackToExpedited) {
  auto id = client.upload(0x1000, 0, block());
  EXPECT_EQ(tick(), Frames{"605#A40010007F000000"});
  EXPECT_EQ(respond("585#8000100001000405"), Frames{"605#4000100000000000"});
  respond("585#4300100091010200");
  EXPECT_TRUE(client.result(id)->fell_back);
  EXPECT_EQ(client.result(id)->data, (Bytes{0x91, 0x01, 0x02, 0x00}));
}

TEST_F(SdoClientTest, OtherAbortsOfBlockInitiateDoNotFallBack) {
  auto id = client.download(0x3000, 0, Bytes(10, 0), block());
  tick();
  EXPECT_EQ(respond("585#8000300000000206"), Frames{});
  EXPECT_EQ(client.result(id)->abort, SdoAbort::ObjectDoesNotExist);
}

TEST_F(SdoClientTest, BlockDownloadWithCrc) {
  auto id = client.download(0x2000, 0, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10}, block());
  EXPECT_EQ(tick(), Frames{"605#C60020000A000000"});
  EXPECT_EQ(respond("585#A40020007F000000"),
            (Frames{"605#0101020304050607", "605#8208090A00000000"}));
  EXPECT_EQ(respond("585#A2027F0000000000"), Frames{"605#D14BCD0000000000"});
  EXPECT_EQ(respond("585#A100000000000000"), Frames{});
  EXPECT_TRUE(client.result(id)->ok());
  EXPECT_EQ(client.result(id)->protocol, SdoProtocol::Block);
}

TEST_F(SdoClientTest, BlockDownloadWithoutServerCrcSendsZeroCrc) {
  client.download(0x2000, 0, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10}, block());
  tick();
  respond("585#A00020007F000000");  // sc=0
  EXPECT_EQ(respond("585#A2027F0000000000"), Frames{"605#D100000000000000"});
}

TEST_F(SdoClientTest, BlockDownloadResendsFromTheSegmentAfterTheAcknowledgedOne) {
  Bytes data(30);
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<std::uint8_t>(i);
  client.download(0x2000, 0, data, block());
  tick();
  // The server asks for blocks of 3: bytes 0..20 in segments 1..3.
  EXPECT_EQ(respond("585#A400200003000000"),
            (Frames{"605#0100010203040506", "605#020708090A0B0C0D", "605#030E0F1011121314"}));
  // Only segment 1 arrived: resend bytes 7.. as segments 1..3, with the new block size 3.
  EXPECT_EQ(respond("585#A201030000000000"),
            (Frames{"605#010708090A0B0C0D", "605#020E0F1011121314", "605#0315161718191A1B"}));
  // All three arrived: the rest (bytes 28, 29) as segment 1 with c=1 (0x81).
  EXPECT_EQ(respond("585#A203030000000000"), Frames{"605#811C1D0000000000"});
}

TEST_F(SdoClientTest, BlockUploadWithCrc) {
  auto id = client.upload(0x1008, 0, block());
  EXPECT_EQ(tick(), Frames{"605#A40810007F000000"});
  EXPECT_EQ(respond("585#C608100014000000"), Frames{"605#A300000000000000"});
  EXPECT_EQ(respond("585#0143414E6F70656E"), Frames{});
  EXPECT_EQ(respond("585#0220746573742064"), Frames{});
  EXPECT_EQ(respond("585#8365766963652100"), Frames{"605#A2037F0000000000"});
  EXPECT_EQ(respond("585#C51D8D0000000000"), Frames{"605#A100000000000000"});
  const std::string text = "CANopen test device!";
  ASSERT_TRUE(client.result(id)->ok());
  EXPECT_EQ(client.result(id)->data, Bytes(text.begin(), text.end()));
}

TEST_F(SdoClientTest, BlockUploadAcknowledgesLastSegmentReceivedInOrder) {
  auto id = client.upload(0x1008, 0, block());
  tick();
  respond("585#C608100014000000");
  respond("585#0143414E6F70656E");
  // Segment 2 lost; the last one arrives: ack 1.
  EXPECT_EQ(respond("585#8365766963652100"), Frames{"605#A2017F0000000000"});
  respond("585#0120746573742064");
  EXPECT_EQ(respond("585#8265766963652100"), Frames{"605#A2027F0000000000"});
  EXPECT_EQ(respond("585#C51D8D0000000000"), Frames{"605#A100000000000000"});
  EXPECT_TRUE(client.result(id)->ok());
}

TEST_F(SdoClientTest, BlockUploadWithWrongCrcAborts) {
  auto id = client.upload(0x1008, 0, block());
  tick();
  respond("585#C608100014000000");
  respond("585#0143414E6F70656E");
  respond("585#0220746573742064");
  respond("585#8365766963652100");
  EXPECT_EQ(respond("585#C51D8E0000000000"), Frames{"605#8008100004000405"});
  EXPECT_EQ(client.result(id)->abort, SdoAbort::CrcError);
}

TEST_F(SdoClientTest, TransfersToOneServerRunOneAfterAnother) {
  auto a = client.upload(0x1000, 0);
  auto b = client.upload(0x1017, 0);
  EXPECT_EQ(client.queued(), 2u);
  EXPECT_EQ(tick(), Frames{"605#4000100000000000"});
  // The first response completes a; b starts right away.
  EXPECT_EQ(respond("585#4300100091010200"), Frames{"605#4017100000000000"});
  EXPECT_EQ(respond("585#4B17100000000000"), Frames{});
  EXPECT_TRUE(client.result(a)->ok());
  EXPECT_TRUE(client.result(b)->ok());
}

TEST_F(SdoClientTest, CallbackMayStartTheNextTransfer) {
  std::vector<SdoAbort> codes;
  client.upload(0x1000, 0, {}, [&](const SdoResult& r) {
    codes.push_back(r.abort);
    client.upload(0x1017, 0, {}, [&](const SdoResult& r2) { codes.push_back(r2.abort); });
  });
  tick();
  EXPECT_EQ(respond("585#4300100091010200"), Frames{"605#4017100000000000"});
  respond("585#8017100000000206");
  EXPECT_EQ(codes, (std::vector<SdoAbort>{SdoAbort::None, SdoAbort::ObjectDoesNotExist}));
}

TEST_F(SdoClientTest, CancelSendsAbortForRunningAndDropsQueuedTransfers) {
  auto a = client.upload(0x1008, 0);
  auto b = client.upload(0x1000, 0);
  tick();
  respond("585#4108100014000000");  // a is running segmented
  EXPECT_TRUE(client.cancel(b, SdoAbort::LocalControl));
  EXPECT_EQ(client.result(b)->abort, SdoAbort::LocalControl);
  EXPECT_TRUE(client.cancel(a));
  EXPECT_EQ(client.next_deadline(), TimePoint{0});
  EXPECT_EQ(tick(), Frames{"605#8008100000000008"});
  EXPECT_EQ(client.result(a)->abort, SdoAbort::General);
  EXPECT_FALSE(client.busy());
  EXPECT_FALSE(client.cancel(a));
}

TEST_F(SdoClientTest, IgnoresFramesOfOtherChannelsAndWhenIdle) {
  std::vector<CanFrame> out;
  EXPECT_FALSE(client.on_frame(*from_candump("586#4300100091010200"), now, out));
  EXPECT_TRUE(client.on_frame(*from_candump("585#4300100091010200"), now, out));
  EXPECT_TRUE(out.empty());
}

TEST(SdoClientMux, RoutesResponsesByCobId) {
  SdoClientMux mux;
  auto a = mux.client(5).upload(0x1000, 0);
  auto b = mux.client(6).upload(0x1000, 0);
  EXPECT_EQ(&mux.client(5), &mux.client(5));
  std::vector<CanFrame> out;
  EXPECT_EQ(mux.next_deadline(), TimePoint{0});
  mux.on_timer(TimePoint{0}, out);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(to_candump(out[0]), "605#4000100000000000");
  EXPECT_EQ(to_candump(out[1]), "606#4000100000000000");
  out.clear();
  EXPECT_TRUE(mux.on_frame(*from_candump("586#4300100001000000"), TimePoint{10}, out));
  EXPECT_FALSE(mux.on_frame(*from_candump("587#4300100001000000"), TimePoint{10}, out));
  EXPECT_EQ(mux.client(6).result(b)->data, (Bytes{1, 0, 0, 0}));
  EXPECT_EQ(mux.client(5).result(a), nullptr);
  EXPECT_TRUE(mux.busy());
}

}  // namespace
}  // namespace nmt
