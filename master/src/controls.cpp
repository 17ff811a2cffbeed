// What a viewer's controls do to a render job: the camera offset that steering adds to the orbit,
// and the time player that picks each frame's time step (by frame, by clock, or as steered).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <voxwall/master/render_job.hpp>
#include <voxwall/net/wire.hpp>

namespace voxwall::master {

void CameraOffset::take(const net::Control& c, const node::Orbit& path) {
  switch (c.command) {
    case net::ControlCommand::Rotate:
      azimuthDeg = std::remainder(azimuthDeg + c.a, 360.0);
      if (azimuthDeg >= 180) azimuthDeg -= 360;
      elevationDeg =
          std::clamp(elevationDeg + c.b, -90.0 - path.elevationDeg, 90.0 - path.elevationDeg);
      break;
    case net::ControlCommand::Zoom:
      zoom = std::clamp(zoom / c.a, 0.05, 20.0);
      break;
    case net::ControlCommand::Pan:
      panX = std::clamp(panX + c.a, -kMaxPan, kMaxPan);
      panY = std::clamp(panY + c.b, -kMaxPan, kMaxPan);
      break;
    case net::ControlCommand::Reset:
      *this = {};
      break;
    default:  // time commands (TimePlayer) move no camera
      break;
  }
}

node::Orbit CameraOffset::apply(node::Orbit orbit) const {
  orbit.azimuthDeg += azimuthDeg;
  orbit.elevationDeg = std::clamp(orbit.elevationDeg + elevationDeg, -90.0, 90.0);
  orbit.distance *= zoom;
  orbit.panX += panX;
  orbit.panY += panY;
  return orbit;
}

int TimeSettings::stepOfFrame(int f, int frames) const {
  const int n = count();
  if (frames <= n) return stepAt(f);
  const int per = std::max(1, frames / n);
  return first + stride * std::min(f / per, n - 1);
}

int TimeSettings::stepAt(long long i) const {
  const long long n = count();
  return first + stride * int(((i % n) + n) % n);
}

TimePlayer::TimePlayer(const TimeSettings& time, int frames, double rate, Clock::time_point start)
    : time_(time), frames_(frames), rate_(rate), anchor_(start) {}

double TimePlayer::clockPosition(Clock::time_point now) const {
  if (!playing_) return position_;
  return position_ + std::chrono::duration<double>(now - anchor_).count() * rate_;
}

void TimePlayer::steer(Clock::time_point now) {
  const double n = time_.count();
  if (rate_ > 0) {
    position_ = clockPosition(now);
    anchor_ = now;
  } else if (!steered_) {
    position_ = lastIndex_;
  }
  position_ -= n * std::floor(position_ / n);
  steered_ = true;
}

bool TimePlayer::take(const net::Control& c, Clock::time_point now) {
  switch (c.command) {
    case net::ControlCommand::Play:
      steer(now);
      playing_ = true;
      return true;
    case net::ControlCommand::Pause:
      steer(now);
      playing_ = false;
      return true;
    case net::ControlCommand::StepBy:
      steer(now);
      position_ = std::floor(position_) + c.a;
      hold_ = true;
      return true;
    case net::ControlCommand::Seek: {
      steer(now);
      const double i = std::round((c.a - time_.first) / time_.stride);
      position_ = std::clamp(i, 0.0, double(time_.count() - 1));
      hold_ = true;
      return true;
    }
    default:
      return false;
  }
}

int TimePlayer::step(int f, Clock::time_point now) {
  const long long n = time_.count();
  long long index = 0;
  if (rate_ > 0) {
    index = (long long)std::floor(clockPosition(now));
  } else if (!steered_) {
    index = (time_.stepOfFrame(f, frames_) - time_.first) / time_.stride;
  } else {
    if (playing_ && !hold_ && lastFrame_ >= 0) position_ += f - lastFrame_;
    position_ -= double(n) * std::floor(position_ / double(n));
    index = (long long)position_;
  }
  hold_ = false;
  lastFrame_ = f;
  lastIndex_ = int(((index % n) + n) % n);
  return time_.first + time_.stride * lastIndex_;
}

int TimePlayer::expectedStep(int f) const {
  if (rate_ <= 0 && !steered_) return time_.stepOfFrame(f, frames_);
  return time_.first + time_.stride * lastIndex_;
}

net::Playback TimePlayer::state() const {
  net::Playback p;
  p.step = std::uint32_t(time_.first + time_.stride * lastIndex_);
  p.first = std::uint32_t(time_.first);
  p.last = std::uint32_t(time_.first + time_.stride * (time_.count() - 1));
  p.stride = std::uint32_t(time_.stride);
  p.playing = playing_;
  p.rate = rate_;
  return p;
}

}  // namespace voxwall::master
