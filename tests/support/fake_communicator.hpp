// A job of N ranks as N threads of one process (IceT's habit: the frame loop is tested without
// MPI). Same contract as the MPI communicator, watchdog included.
#pragma once

#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <voxwall/master/communicator.hpp>

namespace voxwall::test {

class FakeWorld {
 public:
  explicit FakeWorld(int size)
      : size_(size),
        inbox_(std::size_t(size)),
        gathered_(std::size_t(size)),
        abandons_(std::size_t(size)) {}
  int size() const { return size_; }

 private:
  friend class FakeCommunicator;
  int size_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<std::deque<std::vector<std::byte>>> inbox_;     // broadcasts, per receiver
  std::vector<std::deque<std::vector<std::byte>>> gathered_;  // at rank 0, per sender
  std::vector<std::deque<std::uint32_t>> abandons_;  // frames rank 0 abandoned, per receiver
};

class FakeCommunicator final : public master::Communicator {
 public:
  FakeCommunicator(FakeWorld& world, int rank) : world_(world), rank_(rank) {}
  int rank() const override { return rank_; }
  int size() const override { return world_.size(); }
  std::string hostName() const override { return "thread" + std::to_string(rank_); }
  int ranksOnHost() const override { return world_.size(); }

  void broadcast(std::vector<std::byte>& bytes, int timeoutMs) override {
    std::unique_lock lock(world_.mutex_);
    if (rank_ == 0) {
      for (int r = 1; r < size(); ++r) world_.inbox_[std::size_t(r)].push_back(bytes);
      world_.changed_.notify_all();
      return;
    }
    auto& box = world_.inbox_[std::size_t(rank_)];
    if (!world_.changed_.wait_for(lock, std::chrono::milliseconds(timeoutMs),
                                  [&] { return !box.empty(); }))
      throw master::MpiError("watchdog: the master (rank 0) sent nothing");
    bytes = std::move(box.front());
    box.pop_front();
  }

  std::vector<std::vector<std::byte>> gather(std::vector<std::byte> bytes, int timeoutMs,
                                             const std::function<void()>& whileWaiting) override {
    std::unique_lock lock(world_.mutex_);
    if (rank_ != 0) {
      world_.gathered_[std::size_t(rank_)].push_back(std::move(bytes));
      world_.changed_.notify_all();
      return {};
    }
    auto all = [&] {
      for (int r = 1; r < size(); ++r)
        if (world_.gathered_[std::size_t(r)].empty()) return false;
      return true;
    };
    // With something to do while waiting: wait in short steps, unlocked for it.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeoutMs);
    while (whileWaiting && !all() && std::chrono::steady_clock::now() < deadline) {
      world_.changed_.wait_for(lock, std::chrono::milliseconds(2), all);
      lock.unlock();
      whileWaiting();
      lock.lock();
    }
    if (!world_.changed_.wait_until(lock, deadline, all)) {
      std::string who;
      for (int r = 1; r < size(); ++r)
        if (world_.gathered_[std::size_t(r)].empty()) who.append(" ").append(std::to_string(r));
      throw master::MpiError("watchdog: rank(s)" + who + " did not report");
    }
    std::vector<std::vector<std::byte>> out(static_cast<std::size_t>(size()));
    out[0] = std::move(bytes);
    for (int r = 1; r < size(); ++r) {
      out[std::size_t(r)] = std::move(world_.gathered_[std::size_t(r)].front());
      world_.gathered_[std::size_t(r)].pop_front();
    }
    return out;
  }

  void signalAbandon(std::uint32_t frame) override {
    std::lock_guard lock(world_.mutex_);
    for (int r = 1; r < size(); ++r) world_.abandons_[std::size_t(r)].push_back(frame);
  }
  bool abandoned(std::uint32_t frame) override {
    std::lock_guard lock(world_.mutex_);
    auto& box = world_.abandons_[std::size_t(rank_)];
    for (; !box.empty(); box.pop_front()) lastAbandoned_ = box.front();
    return lastAbandoned_ && *lastAbandoned_ == frame;
  }

  [[noreturn]] void abort(int) override { std::terminate(); }

 private:
  FakeWorld& world_;
  int rank_;
  std::optional<std::uint32_t> lastAbandoned_;
};

// Runs `body` on `ranks` threads, one fake rank each; returns each rank's exception (or null).
inline std::vector<std::exception_ptr> runRanks(
    int ranks, const std::function<void(master::Communicator&)>& body) {
  FakeWorld world(ranks);
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(ranks));
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r)
    threads.emplace_back([&, r] {
      FakeCommunicator comm(world, r);
      try {
        body(comm);
      } catch (...) {
        errors[std::size_t(r)] = std::current_exception();
      }
    });
  for (auto& t : threads) t.join();
  return errors;
}

}  // namespace voxwall::test
