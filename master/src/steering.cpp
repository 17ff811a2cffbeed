#include <algorithm>
#include <cmath>
#include <sstream>
#include <voxwall/master/steering.hpp>

namespace voxwall::master {

std::vector<int> parseRefineSteps(const std::string& text) {
  const std::string usage =
      "--refine '" + text + "': expected decreasing steps from 16 down to 1, e.g. 4,2,1";
  std::vector<int> steps;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    std::size_t used = 0;
    int step = 0;
    try {
      step = std::stoi(item, &used);
    } catch (const std::exception&) {
      throw std::invalid_argument(usage);
    }
    if (used != item.size() || step < 1 || step > net::kMaxStep ||
        (!steps.empty() && step >= steps.back()))
      throw std::invalid_argument(usage);
    steps.push_back(step);
  }
  if (steps.empty() || steps.back() != 1) throw std::invalid_argument(usage);
  return steps;
}

Steering::Steering(SteeringSettings settings) : settings_(std::move(settings)) {
  if (settings_.interactiveStep < 1 || settings_.interactiveStep > net::kMaxStep)
    throw std::invalid_argument("--interactive-step must be in [1, " +
                                std::to_string(net::kMaxStep) + "]");
  if (settings_.refine.empty() || settings_.refine.back() != 1)
    throw std::invalid_argument("the refinement must end at full resolution (step 1)");
  if (!(settings_.frameBudgetMs >= 0)) throw std::invalid_argument("a negative frame budget");
}

int Steering::steeringStep() const {
  if (settings_.frameBudgetMs <= 0 || !fullFrameSeconds_) return settings_.interactiveStep;
  // The smallest step whose frame is predicted to fit the budget: full time / s^2 <= budget.
  const double ratio = *fullFrameSeconds_ * 1e3 / settings_.frameBudgetMs;
  const int step = int(std::ceil(std::sqrt(std::max(ratio, 1.0)) - 1e-9));
  return std::clamp(step, 1, net::kMaxStep);
}

FrameChoice Steering::next(int commands, Clock::time_point now) {
  // Batch jobs, and steered jobs told never to reduce (--interactive-step 1, no budget): every
  // frame at full resolution.
  if (!settings_.interactive || (settings_.interactiveStep == 1 && settings_.frameBudgetMs <= 0))
    return {};
  if (commands > 0) {
    lastCommand_ = now;
    shown_.reset();
  }
  if (lastCommand_ &&
      now - *lastCommand_ < std::chrono::duration<double>(settings_.settleSeconds)) {
    const int step = steeringStep();
    return {step, step > 1 ? net::FramePhase::Interactive : net::FramePhase::Full};
  }
  // Settled: the next step finer than what was shown since the last command.
  int step = 1;
  for (const int s : settings_.refine)
    if (!shown_ || s < *shown_) {
      step = s;
      break;
    }
  return {step, step > 1 ? net::FramePhase::Refining : net::FramePhase::Full};
}

bool abandonable(const SteeringSettings& settings, net::FramePhase phase) {
  return settings.interactive && phase != net::FramePhase::Interactive;
}

bool Steering::abandonable(const FrameChoice& frame) const {
  return master::abandonable(settings_, frame.phase);
}

void Steering::predictFullFrame(double seconds) {
  if (!(seconds >= 0)) throw std::invalid_argument("a negative predicted frame time");
  if (!fullFrameSeconds_) fullFrameSeconds_ = seconds;
}

void Steering::finished(const FrameChoice& frame, double seconds, bool abandoned) {
  if (abandoned) return;
  shown_ = shown_ ? std::min(*shown_, frame.step) : frame.step;
  // What this frame says a full one costs; the newest measure counts most.
  const double full = seconds * double(frame.step) * double(frame.step);
  fullFrameSeconds_ = fullFrameSeconds_ ? 0.5 * (*fullFrameSeconds_ + full) : full;
}

}  // namespace voxwall::master
