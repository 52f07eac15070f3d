#pragma once
/// \file Which steps of a dynamic run become frames of motion.xdmf (docs/output.md, "Frames").
///
/// A run of `steps` full steps of h has the states n = 0 ... steps at t = n h. Frames are
/// always full steps (the sub-steps of a step that Newton halved are never written), and the
/// first (n = 0) and the last (n = steps) states are always frames. Between them:
///  - `output: {every: N}`: every N-th step, n = 0, N, 2N, ...;
///  - `output: {interval: T}`: for each k = 0, 1, ... the step nearest k T, n = round(k T / h)
///    (half away from zero); an interval shorter than the step gives every step;
///  - no `output:`: every N = ceil(steps / 200) steps (kDefaultFrames): runs of up to 200 steps
///    write every step, longer ones 101 to 201 frames plus the last state when N does not divide
///    the step count.

#include <string>

namespace flexopt::io {

/// `output:`: which time steps of a dynamic run are written to motion.xdmf (and, when given, at
/// which steps energy and sensors are sampled), or which design iterations of `optimize` are
/// written to design.xdmf. At most one of `every` and `interval`; neither: the defaults of
/// FrameSchedule (dynamic) and every iteration (optimize).
struct OutputSettings {
  int every = 0;       ///< output.every, >= 1; 0: not given
  double interval = 0; ///< output.interval [s] of simulated time, > 0 (dynamic only); 0: not given
  bool given() const { return every > 0 || interval > 0; }
};

class FrameSchedule {
public:
  /// Frames of a run without `output:`: about this many.
  static constexpr long long kDefaultFrames = 200;

  /// Frames of each of an optimization's motion files (motion_initial, motion_final): at most
  /// about this many, whatever output: asks for the run it describes.
  static constexpr long long kOptimizationFrames = 100;

  /// The schedule for `output` (Case::output) over `steps` steps of `h` seconds. With
  /// `at_most` > 0 (an optimization's motions): the default is about `at_most` frames, and a
  /// rule of `output` that would write more is thinned to every ceil(steps / at_most) steps.
  FrameSchedule(const OutputSettings &output, long long steps, double h, long long at_most = 0);

  /// True if the state after step n (n = 0: the initial state; 0 <= n <= steps) is a frame.
  bool is_frame(long long n) const;
  /// Number of frames over the run, the first and the last state included.
  long long frames() const;
  /// The steps between frames when they are regular (`every`, default, or an interval that is
  /// an integer number of steps, up to round-off), else 0.
  long long stride() const { return stride_; }
  /// True if `output.interval` is shorter than the step (every step is then a frame).
  bool interval_below_step() const { return interval_below_step_; }
  /// One line for the run's progress output: the rule and the frame count, e.g.
  /// "201 frames: every 50 steps (the default without output:, about 200 per run)".
  std::string describe() const;

private:
  /// Step of frame k under `interval`: the one nearest k T.
  long long interval_step(long long k) const;

  long long steps_;
  OutputSettings output_;
  long long stride_ = 1;       ///< every-N rule (default, every, and intervals below the step)
  double steps_per_frame_ = 0; ///< interval rule: T / h (> 1); 0 for the every-N rule
  bool interval_below_step_ = false;
  long long at_most_ = 0; ///< the constructor's at_most
  bool thinned_ = false;  ///< output's rule gave more than at_most frames
};

} // namespace flexopt::io
