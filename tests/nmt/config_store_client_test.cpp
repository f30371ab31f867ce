// nmt::ConfigStoreClient: the store operations of DSP 302 §6 as object reads and writes, against
// an in-memory configuration manager, with a recorder of the writes in between.
#include "nmt/manager/config_store_client.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <utility>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/network.hpp"
#include "cfg/object_index.hpp"

namespace {
using namespace cfg::literals;

namespace obj = cfg::object;
using nmt::SdoAbort;
using nmt::StoreAccess;
using Bytes = std::vector<std::uint8_t>;

struct Written {
  cfg::ObjectAddress address;
  Bytes data;
  bool operator==(const Written&) const = default;
};

/// The objects of an in-memory manager, recording every write; `fail_with` makes every access
/// answer that instead (a refusing or silent master).
class RecordingObjects final : public nmt::StoreObjects {
 public:
  explicit RecordingObjects(bool remote = false) : remote_(remote) {}
  cfg::Result<StoreAccess> read(cfg::ObjectAddress address) override {
    if (fail_with) return *fail_with;
    return directory_.read(address);
  }
  cfg::Result<StoreAccess> write(cfg::ObjectAddress address, Bytes data) override {
    written.push_back({address, data});
    if (fail_with) return *fail_with;
    return directory_.write(address, std::move(data));
  }
  bool remote() const override { return remote_; }
  const cfg::ConfigManager& manager() const { return directory_.manager(); }

  std::vector<Written> written;
  std::optional<StoreAccess> fail_with;

 private:
  nmt::StoreDirectoryObjects directory_{cfg::ConfigManager{}};
  bool remote_;
};

/// A node's configuration: 1017h producer heartbeat 100 ms, 1800h sub 2 = FEh.
Bytes concise_stream() {
  const std::vector<cfg::ObjectWrite> writes{{0x1017, 0, {0x64, 0x00}}, {0x1800, 2, {0xFE}}};
  return cfg::encode_concise_dcf(writes);
}

TEST(ConfigStoreClient, PutConciseDcfStoresItThenSetsExpectedDateAndTimeToItsStamp) {
  RecordingObjects objects;
  nmt::ConfigStoreClient client(objects);
  const Bytes stream = concise_stream();
  const auto stamp = client.put(5_node, nmt::StoreFile::Concise, stream);
  ASSERT_TRUE(stamp) << stamp.error().message;
  // DSP 302 §6.6: 1F26h/1F27h are compared with the device's 1020h; the derived master's rule
  // (cfg/network.hpp) is the stamp of the concise DCF of the writes.
  const cfg::ConfigurationStamp expected = cfg::configuration_stamp(stream);
  ASSERT_EQ(stamp.value(), expected);
  EXPECT_EQ(
      objects.written,
      (std::vector<Written>{{{obj::kConciseDcf, 5}, stream},
                            {{obj::kExpectedConfigurationDate, 5}, cfg::le32_bytes(expected.days)},
                            {{obj::kExpectedConfigurationTime, 5}, cfg::le32_bytes(expected.ms)}}));
  EXPECT_EQ(objects.manager().concise(5_node), stream);
  EXPECT_EQ(objects.manager().expected_stamp(5_node), expected);
}

TEST(ConfigStoreClient, PutEdsStoresOnlyTheEdsWithoutAStamp) {
  RecordingObjects objects;
  nmt::ConfigStoreClient client(objects);
  const std::string text = "[FileInfo]\nFileName=x.eds\n";
  const auto stamp = client.put(9_node, nmt::StoreFile::Eds, Bytes(text.begin(), text.end()));
  ASSERT_TRUE(stamp) << stamp.error().message;
  EXPECT_FALSE(stamp.value().has_value());
  ASSERT_EQ(objects.written.size(), 1u);
  EXPECT_EQ(objects.written[0].address, (cfg::ObjectAddress{obj::kStoreEds, 9}));
}

TEST(ConfigStoreClient, PutRefusesAMalformedConciseDcfBeforeWritingAnything) {
  RecordingObjects objects;
  nmt::ConfigStoreClient client(objects);
  // §6.2: the count says 2 entries, one follows.
  Bytes stream = concise_stream();
  stream[0] = 3;
  const auto stamp = client.put(5_node, nmt::StoreFile::Concise, stream);
  ASSERT_FALSE(stamp);
  EXPECT_EQ(stamp.error().category, cfg::ErrorCategory::Input);
  EXPECT_TRUE(objects.written.empty());
}

TEST(ConfigStoreClient, RemoveWritesTheEmptyStreamEmptyFilesAndZeroExpectedDateAndTime) {
  RecordingObjects objects;
  nmt::ConfigStoreClient client(objects);
  ASSERT_TRUE(client.put(5_node, nmt::StoreFile::Concise, concise_stream()));
  objects.written.clear();
  ASSERT_TRUE(client.remove(5_node));
  // §6.2 application hint 1: the empty data set is the stream with count 0; 1F26h/1F27h = 0
  // mean "do not verify" (§6.6).
  const Bytes zero{0, 0, 0, 0};
  EXPECT_EQ(objects.written, (std::vector<Written>{{{obj::kConciseDcf, 5}, zero},
                                                   {{obj::kStoreDcf, 5}, {}},
                                                   {{obj::kStoreEds, 5}, {}},
                                                   {{obj::kExpectedConfigurationDate, 5}, zero},
                                                   {{obj::kExpectedConfigurationTime, 5}, zero}}));
  const auto summary = client.summary(5_node);
  ASSERT_TRUE(summary);
  EXPECT_TRUE(summary->empty());
}

TEST(ConfigStoreClient, ListNamesOnlyNodesWithSomethingStoredWithSizesAndStamp) {
  RecordingObjects objects;
  nmt::ConfigStoreClient client(objects);
  const Bytes stream = concise_stream();
  ASSERT_TRUE(client.put(7_node, nmt::StoreFile::Concise, stream));
  const std::string eds = "[FileInfo]\n";
  ASSERT_TRUE(client.put(3_node, nmt::StoreFile::Eds, Bytes(eds.begin(), eds.end())));
  const auto listed = client.list();
  ASSERT_TRUE(listed) << listed.error().message;
  ASSERT_EQ(listed->size(), 2u);
  const auto& eds_node = (*listed)[0];
  EXPECT_EQ(eds_node.node, 3_node);
  EXPECT_EQ(eds_node.eds_bytes, eds.size());
  // §6.1: nothing stored in 1F20h reads as 0800 0024h, shown as absent.
  EXPECT_EQ(eds_node.dcf_bytes, std::nullopt);
  EXPECT_EQ(eds_node.concise_bytes, 0u);
  const auto& concise_node = (*listed)[1];
  EXPECT_EQ(concise_node.node, 7_node);
  EXPECT_EQ(concise_node.concise_entries, 2u);
  EXPECT_EQ(concise_node.concise_bytes, stream.size());
  EXPECT_EQ(concise_node.stamp, cfg::configuration_stamp(stream));
}

TEST(ConfigStoreClient, ConfigureWritesTheSignatureConfToSub80hForAllNodes) {
  RecordingObjects objects(/*remote=*/true);
  nmt::ConfigStoreClient client(objects);
  // DSP 302 §6.4: sub 80h configures all; the signature 'conf' is 666E6F63h, low byte first.
  (void)client.configure(std::nullopt);
  ASSERT_EQ(objects.written.size(), 1u);
  EXPECT_EQ(objects.written[0], (Written{{obj::kConfigureSlave, 0x80}, Bytes{'c', 'o', 'n', 'f'}}));
  objects.written.clear();
  (void)client.configure(12_node);
  ASSERT_EQ(objects.written.size(), 1u);
  EXPECT_EQ(objects.written[0].address, (cfg::ObjectAddress{obj::kConfigureSlave, 12}));
}

TEST(ConfigStoreClient, ConfigureIsRefusedOnAStoreDirectory) {
  RecordingObjects objects(/*remote=*/false);
  nmt::ConfigStoreClient client(objects);
  const auto done = client.configure(12_node);
  ASSERT_FALSE(done);
  EXPECT_EQ(done.error().category, cfg::ErrorCategory::Input);
  EXPECT_TRUE(objects.written.empty());
}

TEST(ConfigStoreClient, AnAbortNamesTheObjectAndTheCodeInWords) {
  RecordingObjects objects(/*remote=*/true);
  nmt::ConfigStoreClient client(objects);
  objects.fail_with = StoreAccess{SdoAbort::NoDataAvailable, {}, {}, false};
  const auto got = client.get(5_node, nmt::StoreFile::Dcf);
  ASSERT_FALSE(got);
  EXPECT_EQ(got.error().category, cfg::ErrorCategory::Input);
  EXPECT_EQ(got.error().message, "1F20h sub 05h: " + nmt::to_string(SdoAbort::NoDataAvailable));
}

TEST(ConfigStoreClient, AMasterThatDoesNotAnswerIsAnIoFailure) {
  RecordingObjects objects(/*remote=*/true);
  nmt::ConfigStoreClient client(objects);
  // CiA 301: 0504 0000h, the client's own timeout (nmt/io/remote_config_store.hpp sets io).
  objects.fail_with = StoreAccess{SdoAbort::Timeout, {}, {}, true};
  const auto done = client.remove(5_node);
  ASSERT_FALSE(done);
  EXPECT_EQ(done.error().category, cfg::ErrorCategory::Io);
  EXPECT_EQ(done.error().message, "1F22h sub 05h: " + nmt::to_string(SdoAbort::Timeout));
  // The first refused write ends the removal.
  EXPECT_EQ(objects.written.size(), 1u);
}

}  // namespace
