// The few collectives the frame loop needs, behind a small interface (as IceT does) so the loop
// and the balancer run in tests without MPI. Rank 0 is the master and the root of everything.
// Every wait has a deadline (the watchdog): a rank that stops answering ends the job with an
// MpiError naming it, never a silent hang.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace voxwall::master {

// An MPI call that failed, or a rank that did not answer in time; the message names the rank.
class MpiError : public std::runtime_error {
  using std::runtime_error::runtime_error;
};

class Communicator {
 public:
  virtual ~Communicator() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  // The host this rank runs on, and how many ranks of the job share it.
  virtual std::string hostName() const = 0;
  virtual int ranksOnHost() const = 0;
  // Collective: every rank calls this. Rank 0's `bytes` reach every rank (replacing theirs).
  // Throws MpiError when rank 0's message or a receiver does not come within timeoutMs.
  virtual void broadcast(std::vector<std::byte>& bytes, int timeoutMs) = 0;
  // Collective: every rank sends `bytes` to rank 0, which gets all of them (index = rank;
  // its own included); other ranks get an empty list. Throws MpiError naming the ranks that did
  // not answer within timeoutMs. Rank 0 calls `whileWaiting` (if any) every few milliseconds
  // while reports are missing, on this thread (it may signalAbandon).
  virtual std::vector<std::vector<std::byte>> gather(
      std::vector<std::byte> bytes, int timeoutMs,
      const std::function<void()>& whileWaiting = {}) = 0;
  // Rank 0, while frame `frame` renders: tells every other rank at once, without waiting for any,
  // that the frame is abandoned (the camera moved). Not a collective; the frame's gather still
  // happens. Call from the thread that makes the collectives.
  virtual void signalAbandon(std::uint32_t frame) = 0;
  // Other ranks, while rendering `frame`: whether rank 0 abandoned it. Never blocks; a signal
  // for an older frame (one that came after that frame was done) is taken and ignored.
  virtual bool abandoned(std::uint32_t frame) = 0;
  // Ends every rank of the job now (after an error that would strand the others).
  [[noreturn]] virtual void abort(int exitCode) = 0;
};

// A job of one rank (no MPI): broadcast and gather are trivial.
std::unique_ptr<Communicator> makeSingleRankCommunicator();

// Collective: rank 0 gets every rank's text (index = rank); other ranks get an empty list.
std::vector<std::string> gatherStrings(Communicator& comm, const std::string& text, int timeoutMs);
// Collective: every rank gets rank 0's text.
std::string broadcastString(Communicator& comm, const std::string& text, int timeoutMs);

// Collective: every rank calls this with its own verdict (empty = fine). All ranks learn the
// first failure, as "rank R (HOST): <error>", or an empty string when every rank is fine. For
// setup errors, so that no rank goes on alone while another has given up.
std::string agreeOnErrors(Communicator& comm, const std::string& myError, int timeoutMs);

}  // namespace voxwall::master
