#include "protocol/testing/in_memory_network.h"

#include <algorithm>
#include <map>
#include <mutex>
#include <vector>

#include "protocol/ring_queue.h"

namespace edgephys {
namespace {

struct Datagram {
  Endpoint from;
  std::vector<uint8_t> data;  // capacity reused
};

struct Mailbox {
  RingQueue<Datagram> queue;
};

}  // namespace

struct InMemoryNetwork::State {
  explicit State(size_t max_queued) : max_queued_per_socket(max_queued) {}

  Mailbox* Lookup(const Endpoint& to) {
    auto it = bound.find(to);
    if (it != bound.end()) return it->second;
    asio::ip::address any = to.address().is_v4() ? asio::ip::address(asio::ip::address_v4::any())
                                                 : asio::ip::address(asio::ip::address_v6::any());
    it = bound.find(Endpoint(any, to.port()));
    return it != bound.end() ? it->second : nullptr;
  }

  std::mutex mutex;
  size_t max_queued_per_socket;
  std::map<Endpoint, Mailbox*> bound;
  uint16_t next_port = 49152;
  InMemoryNetworkStats stats;
};

namespace {

class InMemorySocket final : public DatagramSocket {
 public:
  InMemorySocket(std::shared_ptr<InMemoryNetwork::State> state, const Endpoint& local)
      : state_(std::move(state)), local_(local) {}

  ~InMemorySocket() override {
    std::lock_guard<std::mutex> lock(state_->mutex);
    auto it = state_->bound.find(local_);
    if (it != state_->bound.end() && it->second == &mailbox_) state_->bound.erase(it);
  }

  Mailbox* mailbox() { return &mailbox_; }

  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
    std::lock_guard<std::mutex> lock(state_->mutex);
    Mailbox* destination = state_->Lookup(to);
    if (destination == nullptr) {
      state_->stats.no_destination++;
      return Status::Ok();  // vanishes, as UDP to a closed port does
    }
    if (destination->queue.size() >= state_->max_queued_per_socket) {
      state_->stats.queue_full++;
      return Status::Ok();
    }
    Datagram& datagram = destination->queue.PushBackSlot();  // reuses the slot's buffer
    datagram.from = local_;
    datagram.data.assign(data.begin(), data.end());
    state_->stats.delivered++;
    return Status::Ok();
  }

  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    std::lock_guard<std::mutex> lock(state_->mutex);
    if (mailbox_.queue.empty()) return 0;
    Datagram& datagram = mailbox_.queue.front();
    size_t size = datagram.data.size();
    std::copy_n(datagram.data.begin(), std::min(size, buffer.size()), buffer.begin());
    *from = datagram.from;
    mailbox_.queue.PopFront();
    return size;
  }

  Endpoint LocalEndpoint() const override { return local_; }

 private:
  std::shared_ptr<InMemoryNetwork::State> state_;
  Endpoint local_;
  Mailbox mailbox_;
};

}  // namespace

InMemoryNetwork::InMemoryNetwork(size_t max_queued_per_socket)
    : state_(std::make_shared<State>(max_queued_per_socket)) {}

InMemoryNetwork::~InMemoryNetwork() = default;

std::unique_ptr<DatagramSocket> InMemoryNetwork::CreateSocket(const Endpoint& address) {
  std::lock_guard<std::mutex> lock(state_->mutex);
  Endpoint local = address;
  if (local.port() == 0) {
    for (int tries = 0; tries < 16384; ++tries) {
      uint16_t port = state_->next_port;
      state_->next_port = port == 65535 ? 49152 : static_cast<uint16_t>(port + 1);
      if (state_->bound.count(Endpoint(address.address(), port)) == 0) {
        local.port(port);
        break;
      }
    }
    if (local.port() == 0) return nullptr;
  }
  if (state_->bound.count(local) != 0) return nullptr;
  auto socket = std::make_unique<InMemorySocket>(state_, local);
  state_->bound[local] = socket->mailbox();
  return socket;
}

InMemoryNetworkStats InMemoryNetwork::stats() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->stats;
}

}  // namespace edgephys
