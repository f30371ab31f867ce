// A master's configuration manager over SDO (nmt/io/remote_config_store.hpp).
#include "nmt/io/remote_config_store.hpp"

#include <utility>

#include "nmt/io/sdo_session.hpp"

namespace nmt {
namespace {

class RemoteStoreObjects final : public StoreObjects {
 public:
  RemoteStoreObjects(std::unique_ptr<SdoSession> session, Duration timeout)
      : session_(std::move(session)) {
    options_.timeout = timeout;
    options_.mode = SdoMode::Block;
  }
  cfg::Result<StoreAccess> read(cfg::ObjectAddress address) override {
    return access(session_->upload(address.index, address.sub_index, options_));
  }
  cfg::Result<StoreAccess> write(cfg::ObjectAddress address,
                                 std::vector<std::uint8_t> data) override {
    return access(session_->download(address.index, address.sub_index, std::move(data), options_));
  }
  bool remote() const override { return true; }

 private:
  static cfg::Result<StoreAccess> access(cfg::Result<SdoResult> result) {
    if (!result) return result.error();
    StoreAccess a;
    a.abort = result->abort;
    a.data = std::move(result->data);
    // The client's own 0504 0000h: the master did not answer, an I/O failure.
    a.io = result->abort == SdoAbort::Timeout;
    return a;
  }

  std::unique_ptr<SdoSession> session_;
  SdoTransferOptions options_;
};

}  // namespace

cfg::Result<std::unique_ptr<StoreObjects>> open_remote_store(const std::string& url,
                                                             cfg::NodeId master, Duration timeout) {
  auto session = SdoSession::open(url, SdoClientConfig::for_node(master));
  if (!session) return session.error();
  return std::unique_ptr<StoreObjects>(
      std::make_unique<RemoteStoreObjects>(std::move(session).value(), timeout));
}

}  // namespace nmt
