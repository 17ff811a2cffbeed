// Each frame's step while a job is steered from the wall, without ranks or a clock: interactive
// frames while commands come, refinement once the camera settled, which frames a command
// abandons, the frame budget, and batch jobs that never reduce, refine or abandon.
#include <gtest/gtest.h>

#include <voxwall/master/render_job.hpp>
#include <voxwall/master/steering.hpp>

using namespace voxwall;
using master::FrameChoice;
using master::Steering;
using master::SteeringSettings;
using namespace std::chrono_literals;

namespace {

SteeringSettings steered(double settleSeconds = 0.5) {
  SteeringSettings s;
  s.interactive = true;
  s.settleSeconds = settleSeconds;
  return s;
}

// Frames one after the other, each taking `seconds`; returns their choices.
std::vector<FrameChoice> frames(Steering& steering, Steering::Clock::time_point& now, int count,
                                int commandsFirst = 0, double seconds = 0.1) {
  std::vector<FrameChoice> out;
  for (int i = 0; i < count; ++i) {
    out.push_back(steering.next(i == 0 ? commandsFirst : 0, now));
    now += std::chrono::duration_cast<Steering::Clock::duration>(
        std::chrono::duration<double>(seconds));
    steering.finished(out.back(), seconds, false);
  }
  return out;
}

}  // namespace

TEST(Steering, ACommandGivesInteractiveFramesThenThePictureRefinesToFullResolution) {
  Steering steering(steered());
  Steering::Clock::time_point now{};
  // Never steered: full frames, which a command may abandon.
  const auto before = frames(steering, now, 2);
  EXPECT_EQ(before[1].step, 1);
  EXPECT_EQ(before[1].phase, net::FramePhase::Full);
  EXPECT_TRUE(steering.abandonable(before[1]));
  // A command: interactive frames at 1/4 until 0.5 s without one; they are never abandoned.
  const auto steeredFrames = frames(steering, now, 5, 1);
  for (const auto& f : steeredFrames) {
    EXPECT_EQ(f.step, 4);
    EXPECT_EQ(f.phase, net::FramePhase::Interactive);
    EXPECT_FALSE(steering.abandonable(f));
  }
  // Settled: 4 was shown already, so 2, then full resolution, and full frames on.
  const auto settled = frames(steering, now, 4);
  EXPECT_EQ(settled[0].step, 2);
  EXPECT_EQ(settled[0].phase, net::FramePhase::Refining);
  EXPECT_TRUE(steering.abandonable(settled[0]));
  EXPECT_EQ(settled[1].step, 1);
  EXPECT_EQ(settled[1].phase, net::FramePhase::Full);
  EXPECT_EQ(settled[3].step, 1);
}

TEST(Steering, WithoutSettlingTimeTheRefinementStartsAtItsCoarsestStep) {
  Steering steering(steered(0));
  Steering::Clock::time_point now{};
  const auto f = frames(steering, now, 4, 1);
  EXPECT_EQ(f[0].step, 4);
  EXPECT_EQ(f[0].phase, net::FramePhase::Refining);
  EXPECT_EQ(f[1].step, 2);
  EXPECT_EQ(f[2].step, 1);
  EXPECT_EQ(f[3].step, 1);
}

TEST(Steering, AnAbandonedFrameIsNotShownSoTheRefinementGoesOnFromWhereItWas) {
  Steering steering(steered(0));
  Steering::Clock::time_point now{};
  const auto coarse = steering.next(1, now);
  steering.finished(coarse, 0.1, false);
  const auto two = steering.next(0, now + 100ms);
  ASSERT_EQ(two.step, 2);
  steering.finished(two, 0.05, true);  // abandoned: step 2 was never shown
  // The next command starts the refinement again from the coarse step.
  EXPECT_EQ(steering.next(1, now + 200ms).step, 4);
}

TEST(Steering, TheFrameBudgetPicksTheSteeringStepFromMeasuredFrames) {
  auto settings = steered();
  settings.frameBudgetMs = 100;
  Steering steering(settings);
  Steering::Clock::time_point now{};
  EXPECT_EQ(steering.steeringStep(), 4);  // nothing measured yet: --interactive-step
  // A full frame of 1.6 s: 1/4 per side takes 0.1 s.
  const auto full = steering.next(0, now);
  steering.finished(full, 1.6, false);
  EXPECT_EQ(steering.steeringStep(), 4);
  EXPECT_EQ(steering.next(1, now + 2s).step, 4);
  // Frames get cheaper (a smaller part of the screen is the volume): a finer step fits.
  steering.finished({4, net::FramePhase::Interactive}, 0.0125, false);  // full: (1.6 + 0.2) / 2
  EXPECT_EQ(steering.steeringStep(), 3);                                // 0.9 s / 9 = 0.1 s
  // A cheap volume: full resolution fits the budget.
  for (int i = 0; i < 20; ++i) steering.finished({1, net::FramePhase::Full}, 0.02, false);
  EXPECT_EQ(steering.steeringStep(), 1);
}

TEST(Steering, BatchJobsAndJobsToldNeverToReduceRenderFullFrames) {
  Steering batch(SteeringSettings{});
  Steering::Clock::time_point now{};
  const auto f = batch.next(3, now);
  EXPECT_EQ(f.step, 1);
  EXPECT_EQ(f.phase, net::FramePhase::Full);
  EXPECT_FALSE(batch.abandonable(f));
  auto never = steered();
  never.interactiveStep = 1;
  Steering full(never);
  EXPECT_EQ(full.next(1, now).step, 1);
  EXPECT_EQ(full.next(0, now + 1s).step, 1);
  EXPECT_TRUE(full.abandonable(full.next(0, now + 2s)));  // still abandoned when the camera moves
}

TEST(Steering, RefineStepsAreParsedAndChecked) {
  EXPECT_EQ(master::parseRefineSteps("4,2,1"), (std::vector<int>{4, 2, 1}));
  EXPECT_EQ(master::parseRefineSteps("1"), (std::vector<int>{1}));
  EXPECT_EQ(master::parseRefineSteps("16,1"), (std::vector<int>{16, 1}));
  for (const char* bad : {"", "4,2", "2,4,1", "4,4,1", "0,1", "17,1", "4,,1", "4x,1", "4 ,1"})
    EXPECT_THROW(master::parseRefineSteps(bad), std::invalid_argument) << bad;
  auto settings = steered();
  settings.refine = {4, 2};
  EXPECT_THROW(Steering{settings}, std::invalid_argument);
}

// Camera commands from the wall cannot wind the camera up: after rotate 0 1e6 the view is at the
// top, and rotate 0 -60 moves it 60 degrees down at once; azimuth wraps; pan stays within reach.
TEST(Steering, CameraCommandsAreClampedAsTheyArrive) {
  node::Orbit path;
  path.azimuthDeg = 30, path.elevationDeg = 20;
  master::CameraOffset offset;
  offset.take({net::ControlCommand::Rotate, 0, 1e6}, path);
  EXPECT_DOUBLE_EQ(offset.apply(path).elevationDeg, 90);
  offset.take({net::ControlCommand::Rotate, 0, -60}, path);
  EXPECT_DOUBLE_EQ(offset.apply(path).elevationDeg, 30);
  offset.take({net::ControlCommand::Rotate, 0, -1e6}, path);
  EXPECT_DOUBLE_EQ(offset.apply(path).elevationDeg, -90);
  offset.take({net::ControlCommand::Rotate, 1e6, 0}, path);
  EXPECT_GE(offset.azimuthDeg, -180);
  EXPECT_LT(offset.azimuthDeg, 180);
  EXPECT_NEAR(offset.azimuthDeg, -80, 1e-6);  // 1e6 = 2778 turns - 80 degrees
  offset.take({net::ControlCommand::Pan, 1e6, -1e6}, path);
  EXPECT_DOUBLE_EQ(offset.panX, master::CameraOffset::kMaxPan);
  EXPECT_DOUBLE_EQ(offset.panY, -master::CameraOffset::kMaxPan);
  offset.take({net::ControlCommand::Pan, -0.5, 0}, path);
  EXPECT_DOUBLE_EQ(offset.panX, master::CameraOffset::kMaxPan - 0.5);
  offset.take({net::ControlCommand::Zoom, 1e-6, 0}, path);
  EXPECT_DOUBLE_EQ(offset.zoom, 20);
  offset.take({net::ControlCommand::Reset, 0, 0}, path);
  EXPECT_DOUBLE_EQ(offset.apply(path).elevationDeg, 20);
  EXPECT_DOUBLE_EQ(offset.panX, 0);
}

// Time commands on a series: until one comes a batch job shows its frames' steps and a playing
// job its clock's; pause holds, step and seek move (wrapping, onto the stride) and the next frame
// shows it; play goes on a step a frame or by the clock.
TEST(Steering, TimeCommandsPauseStepSeekAndPlayTheSeries) {
  using C = net::ControlCommand;
  using Clock = master::TimePlayer::Clock;
  master::TimeSettings range;
  range.first = 2, range.last = 10, range.stride = 2;  // 2, 4, 6, 8, 10
  const Clock::time_point t0{};

  master::TimePlayer byFrame(range, 5, 0, t0);
  EXPECT_EQ(byFrame.step(0, t0), 2);
  EXPECT_EQ(byFrame.step(1, t0), 4);
  EXPECT_FALSE(byFrame.take({C::Rotate, 10, 0}, t0));  // not a time command
  EXPECT_TRUE(byFrame.take({C::Pause, 0, 0}, t0));
  EXPECT_EQ(byFrame.step(2, t0), 4);  // held
  EXPECT_EQ(byFrame.step(3, t0), 4);
  EXPECT_FALSE(byFrame.state().playing);
  byFrame.take({C::StepBy, 1, 0}, t0);
  EXPECT_EQ(byFrame.step(4, t0), 6);
  byFrame.take({C::StepBy, -3, 0}, t0);  // 6 -> 10, wrapping back past 2
  EXPECT_EQ(byFrame.step(5, t0), 10);
  byFrame.take({C::Seek, 5, 0}, t0);  // off the stride: 4 and 6 are as near; rounds to 6
  EXPECT_EQ(byFrame.step(6, t0), 6);
  byFrame.take({C::Seek, 99, 0}, t0);  // past the range: its last step
  EXPECT_EQ(byFrame.step(7, t0), 10);
  byFrame.take({C::Play, 0, 0}, t0);
  EXPECT_EQ(byFrame.step(8, t0), 2);  // on from 10, wrapping
  EXPECT_EQ(byFrame.step(9, t0), 4);
  const net::Playback state = byFrame.state();
  EXPECT_EQ(state, (net::Playback{4, 2, 10, 2, true, 0}));
  // A seek while playing shows the step sought in the next frame, then goes on.
  byFrame.take({C::Seek, 8, 0}, t0);
  EXPECT_EQ(byFrame.step(10, t0), 8);
  EXPECT_EQ(byFrame.step(11, t0), 10);

  // By the clock at 2 steps a second: frames do not matter, time does.
  master::TimePlayer byClock(range, 1000, 2, t0);
  EXPECT_EQ(byClock.step(0, t0 + 100ms), 2);
  EXPECT_EQ(byClock.step(1, t0 + 1200ms), 6);  // index 2.4
  EXPECT_TRUE(byClock.take({C::Pause, 0, 0}, t0 + 1300ms));
  EXPECT_EQ(byClock.step(2, t0 + 9000ms), 6);  // paused: the clock runs on, the step does not
  byClock.take({C::StepBy, 1, 0}, t0 + 9000ms);
  EXPECT_EQ(byClock.step(3, t0 + 9500ms), 8);
  byClock.take({C::Play, 0, 0}, t0 + 10000ms);
  EXPECT_EQ(byClock.step(4, t0 + 10400ms), 8);   // index 3 + 0.8
  EXPECT_EQ(byClock.step(5, t0 + 10600ms), 10);  // index 4.2
  EXPECT_EQ(byClock.step(6, t0 + 11100ms), 2);   // index 5.2: wrapped
  EXPECT_EQ(byClock.state().rate, 2);
}

// Before any frame is measured, a probe's prediction picks the first steered frames' step: a
// bigger screen (a costlier full frame) a coarser one; measured frames then take over.
TEST(Steering, APredictedFullFramePicksTheFirstStepAndABiggerScreenACoarserOne) {
  auto settings = steered();
  settings.frameBudgetMs = 200;
  Steering desktop(settings), wall(settings);
  desktop.predictFullFrame(0.8);  // 0.8 s / 2^2 = 0.2 s
  wall.predictFullFrame(12.0);    // 12 s / 8^2 = 0.19 s
  EXPECT_EQ(desktop.steeringStep(), 2);
  EXPECT_EQ(wall.steeringStep(), 8);
  Steering::Clock::time_point now{};
  EXPECT_EQ(wall.next(1, now).step, 8);  // the first steered frame, before any was measured
  wall.predictFullFrame(1.0);            // a prediction does not replace a measure or another
  EXPECT_EQ(wall.steeringStep(), 8);
  wall.finished({8, net::FramePhase::Interactive}, 0.05, false);  // full: (12 + 3.2) / 2
  EXPECT_EQ(wall.steeringStep(), 7);  // 7.6 s / 49 = 0.16 s (at 6: 0.21 s, over the budget)
  EXPECT_THROW(wall.predictFullFrame(-1), std::invalid_argument);
}
