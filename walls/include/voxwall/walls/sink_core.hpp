// The sink's protocol logic without sockets: the handshake (token, wall, job), what each message
// from a peer does, the frame assembler, the render job's identity and the statistics. The Sink
// (sink.hpp) drives it through net::Server on one thread; tests and the fuzz target drive it from
// bytes.
//
// Jobs: every peer of a render job says the job's id in its Hello. While a job has peers
// connected, a Hello of another job is refused with the reason (so a second job fails at once
// instead of losing frames in silence, and an unauthenticated peer cannot end a running job).
// Once the job's peers are gone, the next job's Hello starts a new frame sequence (logged): the
// old job's open frames are dropped and its later Hellos are refused, so a new job's frame 0 is
// never mistaken for an old frame.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>
#include <voxwall/net/server.hpp>
#include <voxwall/net/wire.hpp>
#include <voxwall/walls/frame_assembler.hpp>
#include <voxwall/walls/log_throttle.hpp>
#include <voxwall/walls/sink.hpp>
#include <voxwall/walls/token_guard.hpp>

namespace voxwall::walls {

class SinkCore {
 public:
  // Gets every complete frame with the job it belongs to (on the calling thread of handle()).
  using Present = std::function<void(std::uint64_t job, AssembledFrame&&)>;
  // Throws std::invalid_argument for settings that cannot work (see FrameAssembler).
  SinkCore(const SinkSettings& settings, SinkLog log, Present present);

  void attach(net::Peer& peer);
  // The connection is gone (closed, dropped or refused); forgets the peer.
  void detach(net::Peer& peer);
  // The largest payload `peer` may send now: kMaxHelloPayload before its Hello was accepted.
  std::uint32_t payloadLimit(const net::Peer& peer) const;
  // One message whose header and payload were checked. Returns false when the session ends (the
  // peer was refused and told why, or it said Bye). Throws FormatError for a peer that broke the
  // protocol (the caller drops it and calls dropped()).
  bool handle(net::Peer& peer, net::MessageType type, std::uint64_t frame,
              std::span<const std::byte> payload);
  // Sends Bye with the reason, counts and logs the refusal, hangs up.
  void refuse(net::Peer& peer, const std::string& reason);
  // Counts and logs a peer dropped for `why` (empty: it simply closed).
  void dropped(net::Peer& peer, const std::string& why);
  // The presenter's word on a complete frame (presented, skipped, not written), told to the
  // job's controller; dropped or refused frames are told by the core itself.
  void frameSettled(std::uint64_t job, std::uint64_t frame, const net::FrameNote& note);
  // Forwards a command to the current job's controller. Returns why it did not: no controller
  // connected, or a time command (play, pause, step, seek) for a job that renders one volume (it
  // presented a frame and never told a time series); empty when sent.
  std::string sendControl(const net::Control& control);

  // Thread-safe.
  SinkStats stats() const;
  template <typename F>
  void updateStats(F f) {
    std::lock_guard lock(statsMutex_);
    f(stats_);
  }
  std::optional<std::uint64_t> currentJob() const { return job_; }
  const FrameAssembler& assembler() const { return assembler_; }

 private:
  bool greet(net::Peer& peer, std::span<const std::byte> payload);
  std::string joinProblem(const net::Peer& peer, const net::Hello& hello);
  bool takeWall(net::Peer& peer, const net::Hello& hello);
  bool endIdleJob(std::uint64_t next);
  // The token check with its per-address back-off; false when the peer was refused.
  bool tokenAccepted(net::Peer& peer, const net::Hello& hello);
  void refuseQuietly(net::Peer& peer, const std::string& reason);
  // Logs `line` about `peer`: at once for a greeted peer, through outsiders_ (by `kind`) for one
  // that is not.
  void sayOf(const net::Peer& peer, const std::string& kind, const std::string& line);
  void onEvent(const FrameEvent& event);
  void say(const std::string& line) {
    if (log_) log_(line);
  }

  const SinkSettings& settings_;
  SinkLog log_;
  Present present_;
  FrameAssembler assembler_;
  std::set<net::Peer*> peers_;
  net::Peer* controller_ = nullptr;
  std::optional<std::uint64_t> job_;
  bool jobPresented_ = false;  // a frame of the current job was presented (lastPresented_)
  std::uint64_t lastPresented_ = 0;
  std::chrono::steady_clock::time_point jobShown_{};  // the job's start or last presented frame
  std::set<std::uint64_t> endedJobs_;
  TokenGuard tokens_;          // the token and its back-off per address
  LogThrottle refusedFrames_;  // frame ids peers send outside the window: a line every 10 s
  // What peers not greeted can make the sink say (refusals, drops, jobs taking the wall): at most
  // 5 lines per kind every 10 s, so a flood of garbage headers or of one-message jobs cannot fill
  // the log (each is still counted in the stats).
  LogThrottle outsiders_{5};
  mutable std::mutex statsMutex_;
  SinkStats stats_;
};

// "0123456789abcdef": how job ids are written in logs.
std::string jobName(std::uint64_t job);

}  // namespace voxwall::walls
