#include "flexopt/io/frame_schedule.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace flexopt::io {

FrameSchedule::FrameSchedule(const OutputSettings &output, long long steps, double h,
                             long long at_most)
    : steps_(std::max(steps, 0LL)), output_(output), at_most_(at_most) {
  if (output.every > 0) {
    stride_ = output.every;
  } else if (output.interval > 0) {
    const double r = output.interval / h; // steps per frame
    const double whole = std::round(r);
    // An interval that is a whole number of steps up to the round-off of T / h (1e-3 / 1e-4 is
    // 9.999999999999998): a regular stride, so the frames do not depend on that round-off.
    if (std::abs(r - whole) <= 1e-9 * r) {
      stride_ = std::max(1LL, static_cast<long long>(whole));
    } else if (r < 1) {
      stride_ = 1;
      interval_below_step_ = true;
    } else {
      stride_ = 0;
      steps_per_frame_ = r;
    }
  } else {
    const long long target = at_most > 0 ? at_most : kDefaultFrames;
    stride_ = std::max(1LL, (steps_ + target - 1) / target);
  }
  if (at_most > 0 && output.given() && frames() > at_most + 2) {
    stride_ = std::max(1LL, (steps_ + at_most - 1) / at_most);
    steps_per_frame_ = 0;
    interval_below_step_ = false;
    thinned_ = true;
  }
}

long long FrameSchedule::interval_step(long long k) const {
  return std::llround(static_cast<double>(k) * steps_per_frame_);
}

bool FrameSchedule::is_frame(long long n) const {
  if (n == 0 || n == steps_) return true;
  if (stride_ > 0) return n % stride_ == 0;
  // round(k r) = n needs k r within [n - 1/2, n + 1/2]: at most two k (r > 1); look around them.
  const auto k0 =
      static_cast<long long>(std::floor((static_cast<double>(n) - 0.5) / steps_per_frame_));
  for (long long k = std::max(0LL, k0 - 1); k <= k0 + 2; ++k)
    if (interval_step(k) == n) return true;
  return false;
}

long long FrameSchedule::frames() const {
  if (stride_ > 0) return steps_ / stride_ + 1 + (steps_ % stride_ != 0 ? 1 : 0);
  // Largest k with round(k r) <= steps, then the last state if it is not that frame.
  auto k =
      static_cast<long long>(std::floor((static_cast<double>(steps_) + 0.5) / steps_per_frame_));
  while (interval_step(k + 1) <= steps_) ++k;
  while (k > 0 && interval_step(k) > steps_) --k;
  return k + 1 + (interval_step(k) != steps_ ? 1 : 0);
}

std::string FrameSchedule::describe() const {
  char buf[256];
  const long long f = frames();
  const std::string stride =
      stride_ == 1 ? "every step" : "every " + std::to_string(stride_) + " steps";
  if (thinned_) {
    std::snprintf(buf, sizeof buf,
                  "%lld frames: %s (output.%s thinned to about %lld frames for an "
                  "optimization's motion)",
                  f, stride.c_str(), output_.every > 0 ? "every" : "interval", at_most_);
  } else if (output_.every > 0) {
    std::snprintf(buf, sizeof buf, "%lld frames: %s (output.every)", f, stride.c_str());
  } else if (output_.interval > 0) {
    if (stride_ > 0)
      std::snprintf(buf, sizeof buf, "%lld frames: %s (output.interval = %g s%s)", f,
                    stride.c_str(), output_.interval,
                    interval_below_step_ ? ", shorter than time.step" : "");
    else
      std::snprintf(buf, sizeof buf,
                    "%lld frames: the step nearest each multiple of output.interval = %g s (%.4g "
                    "steps apart on average)",
                    f, output_.interval, steps_per_frame_);
  } else {
    std::snprintf(buf, sizeof buf,
                  "%lld frames: %s (the default without output:, about %lld per run)", f,
                  stride.c_str(), at_most_ > 0 ? at_most_ : kDefaultFrames);
  }
  std::string s = buf;
  if (f > 1 && stride_ > 0 && steps_ % stride_ != 0) s += ", and the last state";
  return s;
}

} // namespace flexopt::io
