#include <cstring>
#include <voxwall/master/communicator.hpp>

namespace voxwall::master {
namespace {

class SingleRankCommunicator final : public Communicator {
 public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  std::string hostName() const override { return "localhost"; }
  int ranksOnHost() const override { return 1; }
  void broadcast(std::vector<std::byte>&, int) override {}
  std::vector<std::vector<std::byte>> gather(std::vector<std::byte> bytes, int,
                                             const std::function<void()>&) override {
    std::vector<std::vector<std::byte>> all;
    all.push_back(std::move(bytes));
    return all;
  }
  void signalAbandon(std::uint32_t) override {}
  bool abandoned(std::uint32_t) override { return false; }
  [[noreturn]] void abort(int exitCode) override { std::exit(exitCode); }
};

std::vector<std::byte> toBytes(const std::string& text) {
  std::vector<std::byte> bytes(text.size());
  if (!text.empty()) std::memcpy(bytes.data(), text.data(), text.size());
  return bytes;
}

std::string toString(const std::vector<std::byte>& bytes) {
  return std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

}  // namespace

std::unique_ptr<Communicator> makeSingleRankCommunicator() {
  return std::make_unique<SingleRankCommunicator>();
}

std::vector<std::string> gatherStrings(Communicator& comm, const std::string& text, int timeoutMs) {
  std::vector<std::string> out;
  for (const auto& bytes : comm.gather(toBytes(text), timeoutMs)) out.push_back(toString(bytes));
  return out;
}

std::string broadcastString(Communicator& comm, const std::string& text, int timeoutMs) {
  auto bytes = toBytes(text);
  comm.broadcast(bytes, timeoutMs);
  return toString(bytes);
}

std::string agreeOnErrors(Communicator& comm, const std::string& myError, int timeoutMs) {
  const std::string mine = myError.empty() ? std::string()
                                           : "rank " + std::to_string(comm.rank()) + " (" +
                                                 comm.hostName() + "): " + myError;
  std::string verdict;
  for (const auto& e : gatherStrings(comm, mine, timeoutMs))
    if (!e.empty()) {
      verdict = e;
      break;
    }
  return broadcastString(comm, verdict, timeoutMs);
}

}  // namespace voxwall::master
