#include <algorithm>
#include <cstdio>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/files.hpp>
#include <voxwall/core/text.hpp>
#include <voxwall/walls/sink_core.hpp>

namespace voxwall::walls {

namespace {
constexpr std::size_t kEndedJobsKept = 1024;
}

std::string jobName(std::uint64_t job) { return voxwall::hex64(job); }

SinkCore::SinkCore(const SinkSettings& settings, SinkLog log, Present present)
    : settings_(settings),
      log_(std::move(log)),
      present_(std::move(present)),
      assembler_(settings.wall,
                 AssemblerLimits{settings.pendingFrames, settings.pendingBytes,
                                 settings.frameWindow, settings.mosaic},
                 [this](const FrameEvent& e) { onEvent(e); }),
      tokens_(settings.token) {}

void SinkCore::attach(net::Peer& peer) { peers_.insert(&peer); }

void SinkCore::detach(net::Peer& peer) {
  if (peers_.erase(&peer) && peer.greeted() && peer.hello().role == net::Role::Renderer)
    updateStats([](SinkStats& s) { --s.renderersConnected; });
  if (controller_ == &peer) {
    controller_ = nullptr;
    updateStats([](SinkStats& s) { s.controllerConnected = false; });
  }
}

std::uint32_t SinkCore::payloadLimit(const net::Peer& peer) const {
  return peer.greeted() ? net::kMaxPayload : net::kMaxHelloPayload;
}

void SinkCore::sayOf(const net::Peer& peer, const std::string& kind, const std::string& line) {
  if (peer.greeted()) return say(line);
  if (const std::string told = outsiders_.line(kind, line); !told.empty()) say(told);
}

void SinkCore::refuse(net::Peer& peer, const std::string& reason) {
  sayOf(peer, "refused", "sink: refused " + reason);
  refuseQuietly(peer, reason);
}

void SinkCore::refuseQuietly(net::Peer& peer, const std::string& reason) {
  updateStats([](SinkStats& s) { ++s.peersRefused; });
  peer.send(net::encodeMessage(net::Bye{reason.substr(0, net::kMaxString)}));
  peer.hangUp();
  detach(peer);
}

bool SinkCore::tokenAccepted(net::Peer& peer, const net::Hello& hello) {
  const auto result = tokens_.check(peer.address(), hello.token);
  switch (result.verdict) {
    case TokenGuard::Verdict::Accepted:
      return true;
    case TokenGuard::Verdict::BackingOff:
      refuseQuietly(peer, peer.name() + ": too many wrong tokens from " + peer.address() +
                              "; try again in a few seconds");
      return false;
    case TokenGuard::Verdict::Wrong:
      if (result.logLine.empty())
        refuseQuietly(peer, peer.name() + ": wrong token");
      else
        refuse(peer, peer.name() + ": " + result.logLine);
      return false;
  }
  return false;
}

void SinkCore::dropped(net::Peer& peer, const std::string& why) {
  if (!why.empty()) {
    updateStats([](SinkStats& s) { ++s.peersDropped; });
    // Errors about the peer already start with its name.
    const std::string prefix = peer.name() + ": ";
    sayOf(
        peer, "dropped",
        "sink: dropped " + prefix + (why.rfind(prefix, 0) == 0 ? why.substr(prefix.size()) : why));
  }
  detach(peer);
}

void SinkCore::onEvent(const FrameEvent& e) {
  updateStats([&](SinkStats& s) {
    if (e.note.status == net::FrameStatus::Dropped) ++s.framesDropped;
    if (e.note.status == net::FrameStatus::Refused) ++s.framesRefused;
    if (e.note.status == net::FrameStatus::Superseded) ++s.framesSuperseded;
  });
  // Refused frame ids are a peer's to send (ids outside the job's window, thousands a second):
  // their lines are throttled; the controller still hears of each.
  if (e.note.status == net::FrameStatus::Refused) {
    const std::string line = refusedFrames_.line("frame", net::describe(e.frame, e.note));
    if (!line.empty()) say(line);
  } else {
    say(net::describe(e.frame, e.note));
  }
  if (controller_) controller_->send(net::encodeMessage(e.frame, e.note));
}

void SinkCore::frameSettled(std::uint64_t job, std::uint64_t frame, const net::FrameNote& note) {
  if (job_ == job && note.status == net::FrameStatus::Presented) {
    jobPresented_ = true;
    lastPresented_ = frame;
    jobShown_ = std::chrono::steady_clock::now();
  }
  if (controller_ && job_ == job && controller_->hello().jobId == job)
    controller_->send(net::encodeMessage(frame, note));
}

std::string SinkCore::sendControl(const net::Control& control) {
  if (!controller_) return "no render job connected to take the command";
  const bool time = control.command == net::ControlCommand::Play ||
                    control.command == net::ControlCommand::Pause ||
                    control.command == net::ControlCommand::StepBy ||
                    control.command == net::ControlCommand::Seek;
  if (time && jobPresented_ && !stats().playback)
    return "the job renders one volume: play, pause, step and seek have no time to move";
  controller_->send(net::encodeMessage(control));
  return "";
}

SinkStats SinkCore::stats() const {
  std::lock_guard lock(statsMutex_);
  return stats_;
}

bool SinkCore::greet(net::Peer& peer, std::span<const std::byte> payload) {
  const net::Hello hello = net::decodeHello(payload, peer.name());
  if (!tokenAccepted(peer, hello)) return false;
  const Wall& wall = settings_.wall;
  if (!hello.wallId.empty() && hello.wallId != wall.id) {
    refuse(peer, peer.name() + ": renders for wall " + quotedForLog(hello.wallId, 64) +
                     ", this sink shows '" + wall.id + "'");
    return false;
  }
  if (endedJobs_.count(hello.jobId)) {
    refuse(peer, peer.name() + ": job " + jobName(hello.jobId) +
                     " has ended: a newer job took this wall");
    return false;
  }
  if (job_ == hello.jobId) {
    if (const std::string why = joinProblem(peer, hello); !why.empty()) {
      refuse(peer, peer.name() + ": " + why);
      return false;
    }
  } else if (!takeWall(peer, hello)) {
    return false;
  }
  peer.markGreeted(hello, peer.name() + (hello.role == net::Role::Controller
                                             ? " (controller)"
                                             : " (rank " + std::to_string(hello.rank) + ")"));
  updateStats([](SinkStats& s) { ++s.peersAccepted; });
  if (hello.role == net::Role::Controller) {
    controller_ = &peer;
    updateStats([](SinkStats& s) { s.controllerConnected = true; });
  } else {
    updateStats([](SinkStats& s) { ++s.renderersConnected; });
  }
  // Ranks cut their segments at the display edges and send bezel-only ones when the sink writes
  // the whole screen (--mosaic).
  net::Welcome welcome{wall.id, wall.width, wall.height, {}, settings_.mosaic};
  for (const auto& d : wall.displays) welcome.displays.push_back(d.rect);
  peer.send(net::encodeMessage(welcome));
  // A controller that connects after its job's frames were shown (its job fails when it hears
  // of none) is told of the last one.
  if (hello.role == net::Role::Controller && jobPresented_)
    peer.send(net::encodeMessage(lastPresented_, net::FrameNote{net::FrameStatus::Presented, ""}));
  return true;
}

// A peer of another job than the running one: its job takes the wall once the running job has
// no peer left; false (the peer refused) while it has.
bool SinkCore::takeWall(net::Peer& peer, const net::Hello& hello) {
  if (job_) {
    // One job at a time: a running job keeps the wall; once all its peers are gone, the next
    // job takes it and the old one can never come back (its frame ids would mean nothing).
    int running = 0;
    for (const net::Peer* other : peers_)
      running += other != &peer && other->greeted() && other->hello().jobId == *job_;
    if (running > 0 && endIdleJob(hello.jobId)) running = 0;
    if (running > 0) {
      // The running job's id is its peers' secret (whoever says it joins the job): the log
      // names it, the refused peer hears only that a job is showing.
      const std::string showing = " is showing on this wall (" + std::to_string(running) +
                                  " peer(s) connected); try again when it ends";
      sayOf(peer, "refused", "sink: refused " + peer.name() + ": job " + jobName(*job_) + showing);
      refuseQuietly(peer, peer.name() + ": a job" + showing);
      return false;
    }
    const std::string why =
        "job " + jobName(*job_) + " ended; job " + jobName(hello.jobId) + " took the wall";
    sayOf(peer, "jobs", "sink: " + why);
    endedJobs_.insert(*job_);
    if (endedJobs_.size() > kEndedJobsKept) endedJobs_.erase(endedJobs_.begin());
    assembler_.startSequence(hello.nextFrame, why);
  } else {
    sayOf(peer, "jobs", "sink: job " + jobName(hello.jobId) + " started");
    assembler_.startSequence(hello.nextFrame, "");
  }
  job_ = hello.jobId;
  jobPresented_ = false;
  jobShown_ = std::chrono::steady_clock::now();
  updateStats([](SinkStats& s) { s.playback.reset(); });
  return true;
}

// The running job, when it has presented no frame for --job-idle, gives the wall up to job
// `next`: its peers hear why and are hung up on. Whether it did.
bool SinkCore::endIdleJob(std::uint64_t next) {
  const auto idle = std::chrono::steady_clock::now() - jobShown_;
  if (idle < std::chrono::milliseconds(settings_.jobIdleMs)) return false;
  const std::string why =
      "job " + jobName(*job_) + " presented no frame for " +
      std::to_string(std::chrono::duration_cast<std::chrono::seconds>(idle).count()) +
      " s (--job-idle); job " + jobName(next) + " asked for the wall";
  say("sink: " + why);
  std::vector<net::Peer*> old;
  for (net::Peer* other : peers_)
    if (other->greeted() && other->hello().jobId == *job_) old.push_back(other);
  for (net::Peer* other : old) {
    other->send(net::encodeMessage(net::Bye{"this job presented no frame for " +
                                            formatLine("%g", settings_.jobIdleMs / 1e3) +
                                            " s (--job-idle) and another job took the wall"}));
    other->hangUp();
    detach(*other);
  }
  return true;
}

// A job has one controller and each of its ranks once, all its peers agreeing on how many ranks
// it has. The job's id is a secret only its ranks know (the sink never tells it), so a peer that
// says it and a place the job has filled is that place reconnecting (its old connection not yet
// found dead): it takes the place and the old connection is hung up on. A rank count other than
// the job's is refused.
std::string SinkCore::joinProblem(const net::Peer& peer, const net::Hello& hello) {
  net::Peer* samePlace = nullptr;
  for (net::Peer* other : peers_) {
    if (other == &peer || !other->greeted() || other->hello().jobId != hello.jobId) continue;
    const net::Hello& them = other->hello();
    if (them.rankCount != hello.rankCount)
      return "says the job has " + std::to_string(hello.rankCount) + " ranks where " +
             other->name() + " says " + std::to_string(them.rankCount);
    if (them.role == hello.role && (hello.role == net::Role::Controller || them.rank == hello.rank))
      samePlace = other;
  }
  if (samePlace) {
    say("sink: " + samePlace->name() + " replaced by " + peer.name() +
        " (the same place of the job connected again)");
    samePlace->send(net::encodeMessage(net::Bye{"replaced by a new connection of the same place"}));
    samePlace->hangUp();
    detach(*samePlace);
  }
  return "";
}

bool SinkCore::handle(net::Peer& peer, net::MessageType type, std::uint64_t frame,
                      std::span<const std::byte> payload) {
  using net::MessageType;
  if (payload.size() > payloadLimit(peer))
    throw FormatError(peer.name(),
                      "payload of " + std::to_string(payload.size()) + " bytes before its Hello");
  if (!peer.greeted()) {
    if (type != MessageType::Hello) {
      refuse(peer, peer.name() + ": sent a message before Hello");
      return false;
    }
    return greet(peer, payload);
  }
  // A peer of a job that was replaced is being hung up on; what it still sends is not read.
  if (peer.hello().jobId != job_) return false;
  switch (type) {
    case MessageType::Tile: {
      if (peer.hello().role != net::Role::Renderer)
        throw FormatError(peer.name(), "a controller sent a tile");
      auto tile = net::decodeTileMessage(payload, peer.name());
      if (auto done = assembler_.addTile(frame, std::move(tile), peer.hello().rank, peer.name()))
        present_(*job_, std::move(*done));
      return true;
    }
    case MessageType::FrameEnd: {
      if (peer.hello().role != net::Role::Renderer)
        throw FormatError(peer.name(), "a controller sent a FrameEnd");
      const auto end = net::decodeFrameEnd(payload, peer.name());
      if (end.rank != peer.hello().rank)
        throw FormatError(peer.name(), "rank " + std::to_string(peer.hello().rank) +
                                           " sent the FrameEnd of rank " +
                                           std::to_string(end.rank));
      if (end.abandoned)
        assembler_.supersede(frame, "the render job abandoned it (the camera moved)");
      return true;
    }
    case MessageType::Playback: {
      if (peer.hello().role != net::Role::Controller)
        throw FormatError(peer.name(), "a renderer sent a Playback");
      auto playback = net::decodePlayback(payload, peer.name());
      updateStats([&](SinkStats& s) { s.playback = playback; });
      return true;
    }
    case MessageType::Bye:
      peer.hangUp();
      detach(peer);
      return false;
    case MessageType::KeepAlive:  // the server counts it as a sign of life; nothing else
      if (!payload.empty()) throw FormatError(peer.name(), "a KeepAlive with a payload");
      return true;
    default:
      throw FormatError(peer.name(), "unexpected message type " + std::to_string(int(type)));
  }
}

}  // namespace voxwall::walls
