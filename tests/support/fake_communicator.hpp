// A job of N ranks as N threads of one process (IceT's habit: the frame loop is tested without
// MPI). Same contract as the MPI communicator, watchdog included.
#pragma once

#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <voxwall/master/communicator.hpp>

namespace voxwall::test {

class FakeWorld {
 public:
  explicit FakeWorld(int size)
      : size_(size), inbox_(std::size_t(size)), gathered_(std::size_t(size)) {}
  int size() const { return size_; }

 private:
  friend class FakeCommunicator;
  int size_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<std::deque<std::vector<std::byte>>> inbox_;     // broadcasts, per receiver
  std::vector<std::deque<std::vector<std::byte>>> gathered_;  // at rank 0, per sender
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

  std::vector<std::vector<std::byte>> gather(std::vector<std::byte> bytes, int timeoutMs) override {
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
    if (!world_.changed_.wait_for(lock, std::chrono::milliseconds(timeoutMs), all)) {
      std::string who;
      for (int r = 1; r < size(); ++r)
        if (world_.gathered_[std::size_t(r)].empty()) who += " " + std::to_string(r);
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

  [[noreturn]] void abort(int) override { std::terminate(); }

 private:
  FakeWorld& world_;
  int rank_;
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
