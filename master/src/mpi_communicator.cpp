// Collectives built from point-to-point messages with a deadline. Rank 0 is the root. Message
// tags keep broadcasts and gathers apart; MPI keeps messages of one tag between two ranks in
// order, so frame f's messages can never be taken for frame f+1's.
#include <mpi.h>

#include <chrono>
#include <cstdlib>
#include <deque>
#include <limits>
#include <optional>
#include <string>
#include <thread>
#include <voxwall/master/mpi_communicator.hpp>

namespace voxwall::master {
namespace {

constexpr int kTagBroadcast = 101;
constexpr int kTagGather = 102;
constexpr int kTagAbandon = 103;

std::string mpiErrorString(int code) {
  char text[MPI_MAX_ERROR_STRING];
  int length = 0;
  MPI_Error_string(code, text, &length);
  return std::string(text, std::size_t(length));
}

void check(int code, const char* call, int rank) {
  if (code != MPI_SUCCESS)
    throw MpiError("rank " + std::to_string(rank) + ": " + call + ": " + mpiErrorString(code));
}

using Clock = std::chrono::steady_clock;

int messageCount(const std::vector<std::byte>& bytes, int rank) {
  if (bytes.size() > std::size_t(std::numeric_limits<int>::max()))
    throw MpiError("rank " + std::to_string(rank) + ": a message of " +
                   std::to_string(bytes.size()) + " bytes is over MPI's 2 GiB limit");
  return int(bytes.size());
}

// Polls with a growing pause (up to 1 ms) so a waiting rank costs next to no CPU.
class Poller {
 public:
  explicit Poller(int timeoutMs) : deadline_(Clock::now() + std::chrono::milliseconds(timeoutMs)) {}
  bool expired() const { return Clock::now() > deadline_; }
  void pause() {
    std::this_thread::sleep_for(std::chrono::microseconds(pauseUs_));
    pauseUs_ = std::min(pauseUs_ * 2, 1000);
  }

 private:
  Clock::time_point deadline_;
  int pauseUs_ = 10;
};

std::string seconds(int ms) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f s", ms / 1000.0);
  return text;
}

class MpiCommunicator final : public Communicator {
 public:
  MpiCommunicator() {
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    char name[MPI_MAX_PROCESSOR_NAME];
    int length = 0;
    MPI_Get_processor_name(name, &length);
    host_.assign(name, std::size_t(length));
    MPI_Comm shared;
    check(MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &shared),
          "MPI_Comm_split_type", rank_);
    MPI_Comm_size(shared, &onHost_);
    MPI_Comm_free(&shared);
  }
  ~MpiCommunicator() override {
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (!finalized) MPI_Finalize();
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  std::string hostName() const override { return host_; }
  int ranksOnHost() const override { return onHost_; }

  void broadcast(std::vector<std::byte>& bytes, int timeoutMs) override {
    if (size_ == 1) return;
    if (rank_ == 0) {
      std::vector<MPI_Request> requests(std::size_t(size_ - 1));
      for (int r = 1; r < size_; ++r)
        check(MPI_Isend(bytes.data(), messageCount(bytes, rank_), MPI_BYTE, r, kTagBroadcast,
                        MPI_COMM_WORLD, &requests[std::size_t(r - 1)]),
              "MPI_Isend", rank_);
      waitAll(requests, timeoutMs, "did not take the frame task");
      return;
    }
    bytes = receive(0, kTagBroadcast, timeoutMs,
                    "the master (rank 0) sent nothing for " + seconds(timeoutMs));
  }

  std::vector<std::vector<std::byte>> gather(std::vector<std::byte> bytes, int timeoutMs,
                                             const std::function<void()>& whileWaiting) override {
    std::vector<std::vector<std::byte>> all;
    if (rank_ != 0) {
      MPI_Request request;
      check(MPI_Isend(bytes.data(), messageCount(bytes, rank_), MPI_BYTE, 0, kTagGather,
                      MPI_COMM_WORLD, &request),
            "MPI_Isend", rank_);
      std::vector<MPI_Request> requests{request};
      waitAll(requests, timeoutMs, "(the master) did not take this rank's report");
      return all;
    }
    all.resize(std::size_t(size_));
    all[0] = std::move(bytes);
    std::vector<bool> got(std::size_t(size_), false);
    got[0] = true;
    int missing = size_ - 1;
    Poller poll(timeoutMs);
    while (missing > 0) {
      bool progress = false;
      for (int r = 1; r < size_; ++r) {
        if (got[std::size_t(r)]) continue;
        int flag = 0;
        MPI_Status status;
        check(MPI_Iprobe(r, kTagGather, MPI_COMM_WORLD, &flag, &status), "MPI_Iprobe", rank_);
        if (!flag) continue;
        all[std::size_t(r)] = receiveProbed(status, r, kTagGather);
        got[std::size_t(r)] = true;
        --missing;
        progress = true;
      }
      if (missing == 0 || progress) continue;
      if (whileWaiting) whileWaiting();
      if (poll.expired()) {
        std::string who;
        for (int r = 1; r < size_; ++r)
          if (!got[std::size_t(r)]) who += (who.empty() ? "" : ", ") + std::to_string(r);
        throw MpiError("watchdog: rank" + std::string(missing > 1 ? "s " : " ") + who +
                       " did not report within " + seconds(timeoutMs) +
                       " (stopped, hung, or much slower than the watchdog allows)");
      }
      poll.pause();
    }
    return all;
  }

  void signalAbandon(std::uint32_t frame) override {
    if (rank_ != 0) return;
    // The frame number stays where MPI can read it until the send completes (a deque keeps
    // addresses); the requests complete on their own (a few bytes each).
    abandonSent_.push_back(frame);
    for (int r = 1; r < size_; ++r) {
      MPI_Request request;
      check(MPI_Isend(&abandonSent_.back(), 1, MPI_UINT32_T, r, kTagAbandon, MPI_COMM_WORLD,
                      &request),
            "MPI_Isend", rank_);
      check(MPI_Request_free(&request), "MPI_Request_free", rank_);
    }
  }

  bool abandoned(std::uint32_t frame) override {
    if (rank_ == 0) return false;
    for (;;) {
      int flag = 0;
      MPI_Status status;
      check(MPI_Iprobe(0, kTagAbandon, MPI_COMM_WORLD, &flag, &status), "MPI_Iprobe", rank_);
      if (!flag) break;
      std::uint32_t got = 0;
      check(MPI_Recv(&got, 1, MPI_UINT32_T, 0, kTagAbandon, MPI_COMM_WORLD, MPI_STATUS_IGNORE),
            "MPI_Recv", rank_);
      lastAbandoned_ = got;
    }
    return lastAbandoned_ && *lastAbandoned_ == frame;
  }

  [[noreturn]] void abort(int exitCode) override {
    MPI_Abort(MPI_COMM_WORLD, exitCode);
    std::_Exit(exitCode);
  }

 private:
  std::vector<std::byte> receive(int source, int tag, int timeoutMs, const std::string& onTimeout) {
    Poller poll(timeoutMs);
    for (;;) {
      int flag = 0;
      MPI_Status status;
      check(MPI_Iprobe(source, tag, MPI_COMM_WORLD, &flag, &status), "MPI_Iprobe", rank_);
      if (flag) return receiveProbed(status, source, tag);
      if (poll.expired()) throw MpiError("watchdog: " + onTimeout);
      poll.pause();
    }
  }

  std::vector<std::byte> receiveProbed(const MPI_Status& status, int source, int tag) {
    int count = 0;
    MPI_Status probed = status;
    check(MPI_Get_count(&probed, MPI_BYTE, &count), "MPI_Get_count", rank_);
    std::vector<std::byte> bytes(static_cast<std::size_t>(count));
    check(MPI_Recv(bytes.data(), count, MPI_BYTE, source, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE),
          "MPI_Recv", rank_);
    return bytes;
  }

  void waitAll(std::vector<MPI_Request>& requests, int timeoutMs, const std::string& what) {
    Poller poll(timeoutMs);
    for (;;) {
      int done = 0;
      check(MPI_Testall(int(requests.size()), requests.data(), &done, MPI_STATUSES_IGNORE),
            "MPI_Testall", rank_);
      if (done) return;
      if (poll.expired()) {
        std::string who;
        if (rank_ == 0)
          for (std::size_t i = 0; i < requests.size(); ++i) {
            int flag = 0;
            MPI_Test(&requests[i], &flag, MPI_STATUS_IGNORE);
            if (!flag) who += (who.empty() ? "rank " : ", ") + std::to_string(i + 1);
          }
        else
          who = "rank 0";
        throw MpiError("watchdog: " + who + " " + what + " within " + seconds(timeoutMs));
      }
      poll.pause();
    }
  }

  int rank_ = 0, size_ = 1, onHost_ = 1;
  std::string host_;
  std::deque<std::uint32_t> abandonSent_;       // rank 0: the frames it abandoned
  std::optional<std::uint32_t> lastAbandoned_;  // other ranks: the newest frame rank 0 abandoned
};

}  // namespace

bool launchedByMpi() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS"})
    if (std::getenv(name)) return true;
  return false;
}

std::unique_ptr<Communicator> makeMpiCommunicator(int* argc, char*** argv) {
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (!initialized) {
    int provided = 0;
    const int code = MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
    if (code != MPI_SUCCESS) throw MpiError("MPI_Init_thread: " + mpiErrorString(code));
  }
  return std::make_unique<MpiCommunicator>();
}

}  // namespace voxwall::master
