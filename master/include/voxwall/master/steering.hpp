// What resolution each frame of a job that is steered from the wall is rendered at, and which
// frames may be abandoned when the camera moves. Rank 0's frame loop asks it once per frame;
// no MPI, no sockets, no clock of its own (the caller passes the time), so it is unit-tested.
//
//   - While camera commands keep coming (the last one less than settleSeconds ago), frames are
//     *interactive*: rendered at 1/steeringStep per side. With a frame budget the step is the
//     smallest one whose predicted frame time fits the budget, predicted from a probe of the view
//     before the first frame (predictFullFrame) and then from the frames so far (a frame at step
//     s costs about the full frame's time / s^2); without one, interactiveStep.
//   - Once the camera settled, the picture *refines*: each frame at the next step of `refine`
//     finer than the last one shown since the last command, down to full resolution.
//   - A command that arrives while a refining or full frame renders abandons that frame (the
//     frame loop asks abandonable()); interactive frames are never abandoned: they are the fast
//     ones, and a drag sends commands faster than any frame renders.
//   - Jobs that write frames, or do not stream to a sink, are batch jobs: every frame is a full
//     one and none is abandoned.
#pragma once

#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>
#include <voxwall/net/wire.hpp>

namespace voxwall::master {

struct SteeringSettings {
  bool interactive = false;  // a job steered from the wall (streaming, writing no frames)
  int interactiveStep = 4;   // the step while steering, without a frame budget (1: never reduce)
  std::vector<int> refine = {4, 2, 1};  // the steps once the camera settled, coarse to full
  double settleSeconds = 0.5;           // no command for this long: the camera settled
  double frameBudgetMs = 0;  // > 0: the steering step keeps an interactive frame near this
};

// "4,2,1" -> {4, 2, 1}: decreasing steps in [1, 16] that end at 1. Throws std::invalid_argument
// naming --refine.
std::vector<int> parseRefineSteps(const std::string& text);

struct FrameChoice {
  int step = 1;
  net::FramePhase phase = net::FramePhase::Full;
};

// Whether a frame of this phase may be abandoned in a job with these settings (every rank asks
// the same question of the same frame task).
bool abandonable(const SteeringSettings& settings, net::FramePhase phase);

class Steering {
 public:
  using Clock = std::chrono::steady_clock;
  // Throws std::invalid_argument for settings that cannot work.
  explicit Steering(SteeringSettings settings);

  // The frame starting now, `commands` camera commands after the last one.
  FrameChoice next(int commands, Clock::time_point now);
  // Whether a camera command arriving while `frame` renders abandons it.
  bool abandonable(const FrameChoice& frame) const;
  // The frame ended after `seconds` (camera decided -> frame done), or was abandoned.
  void finished(const FrameChoice& frame, double seconds, bool abandoned);
  // Whether frames are steered from the wall (SteeringSettings::interactive).
  bool interactive() const { return settings_.interactive; }
  // The step steered frames are rendered at now.
  int steeringStep() const;
  // The predicted full-resolution frame time, once a frame was measured or predicted.
  std::optional<double> fullFrameSeconds() const { return fullFrameSeconds_; }
  // A full-resolution frame's time predicted before any frame was measured (a probe of the
  // view), so that the first steered frame keeps the budget; measured frames then take over.
  void predictFullFrame(double seconds);

 private:
  SteeringSettings settings_;
  std::optional<Clock::time_point> lastCommand_;
  // The step of the finest frame shown since the last command (none: nothing yet); full
  // resolution before any command, so a job that is never steered never refines.
  std::optional<int> shown_ = 1;
  std::optional<double> fullFrameSeconds_;
};

}  // namespace voxwall::master
