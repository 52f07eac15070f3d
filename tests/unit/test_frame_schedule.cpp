// io::FrameSchedule: which steps of a dynamic run are motion frames (docs/output.md, "Frames"),
// the motion file size estimate's arithmetic, and design.xdmf's frames and size for optimize.
#include "flexopt/io/frame_schedule.hpp"
#include "flexopt/io/motion_writer.hpp"
#include "flexopt/io/xdmf.hpp"
#include "flexopt/optimize/optimizer.hpp"

#include <algorithm>
#include <cmath>
#include <gtest/gtest.h>
#include <vector>

using flexopt::io::FrameSchedule;
using flexopt::io::OutputSettings;

namespace {

/// The frame steps of a schedule, by asking is_frame for every state 0 ... steps.
std::vector<long long> frame_steps(const FrameSchedule &s, long long steps) {
  std::vector<long long> out;
  for (long long n = 0; n <= steps; ++n)
    if (s.is_frame(n)) out.push_back(n);
  return out;
}

OutputSettings every(int n) {
  OutputSettings o;
  o.every = n;
  return o;
}

OutputSettings interval(double t) {
  OutputSettings o;
  o.interval = t;
  return o;
}

} // namespace

TEST(FrameSchedule, DefaultKeepsShortRunsWhole) {
  const FrameSchedule s(OutputSettings{}, 200, 1e-3);
  EXPECT_EQ(s.stride(), 1);
  EXPECT_EQ(s.frames(), 201);
  EXPECT_EQ(frame_steps(s, 200).size(), 201u);
}

TEST(FrameSchedule, DefaultBoundsLongRuns) {
  // 10,000 steps: every 50 steps, 201 frames with the first and the last state.
  const FrameSchedule s(OutputSettings{}, 10000, 1e-5);
  EXPECT_EQ(s.stride(), 50);
  const auto f = frame_steps(s, 10000);
  ASSERT_EQ(static_cast<long long>(f.size()), s.frames());
  EXPECT_EQ(f.size(), 201u);
  EXPECT_EQ(f.front(), 0);
  EXPECT_EQ(f.back(), 10000);
  // Any length: between 101 and 202 frames once the run is longer than 200 steps.
  for (long long steps : {201LL, 299LL, 401LL, 12345LL, 1000000LL, 9999999LL}) {
    const FrameSchedule d(OutputSettings{}, steps, 1e-5);
    EXPECT_GE(d.frames(), 101) << steps;
    EXPECT_LE(d.frames(), 202) << steps;
    EXPECT_TRUE(d.is_frame(0) && d.is_frame(steps)) << steps;
  }
  const FrameSchedule odd(OutputSettings{}, 12345, 1e-5); // stride 62: 12345 = 199 * 62 + 7
  const auto g = frame_steps(odd, 12345);
  EXPECT_EQ(static_cast<long long>(g.size()), odd.frames());
  EXPECT_EQ(g[g.size() - 2], 199 * 62);
  EXPECT_EQ(g.back(), 12345);
}

TEST(FrameSchedule, EveryNAndTheLastState) {
  const FrameSchedule s(every(7), 100, 1e-3);
  const auto f = frame_steps(s, 100);
  // 0, 7, ..., 98, then the last state 100.
  ASSERT_EQ(f.size(), 16u);
  EXPECT_EQ(s.frames(), 16);
  EXPECT_EQ(f[14], 98);
  EXPECT_EQ(f[15], 100);
  EXPECT_EQ(FrameSchedule(every(1), 100, 1e-3).frames(), 101);
  EXPECT_EQ(FrameSchedule(every(1000000), 100, 1e-3).frames(), 2); // first and last only
  EXPECT_EQ(FrameSchedule(every(10), 0, 1e-3).frames(), 1);        // no step: the initial state
}

TEST(FrameSchedule, IntervalOfWholeStepsIsAStride) {
  // 1e-3 / 1e-4 is 9.999999999999998 in floating point: still every 10 steps.
  const FrameSchedule s(interval(1e-3), 1000, 1e-4);
  EXPECT_EQ(s.stride(), 10);
  EXPECT_EQ(s.frames(), 101);
  EXPECT_EQ(FrameSchedule(interval(0.3), 1000, 1e-3).frames(), 5); // 0, 300, 600, 900, 1000
}

TEST(FrameSchedule, IntervalBetweenStepsTakesTheNearestStep) {
  // T = 12.5 steps: round(12.5 k) (half away from zero) = 0, 13, 25, 38, 50, ...
  const FrameSchedule s(interval(0.0125), 1000, 1e-3);
  EXPECT_EQ(s.stride(), 0);
  const auto f = frame_steps(s, 1000);
  ASSERT_EQ(static_cast<long long>(f.size()), s.frames());
  ASSERT_EQ(f.size(), 81u); // k = 0 ... 80, 80 * 12.5 = 1000: the last state
  for (std::size_t k = 0; k < f.size(); ++k)
    EXPECT_EQ(f[k], std::llround(12.5 * static_cast<double>(k))) << k;
  // The last state is added when no multiple falls on it: T = 3.7 steps over 20 steps.
  const FrameSchedule t(interval(3.7e-3), 20, 1e-3);
  EXPECT_EQ(frame_steps(t, 20), (std::vector<long long>{0, 4, 7, 11, 15, 19, 20}));
  EXPECT_EQ(t.frames(), 7);
}

TEST(FrameSchedule, IntervalBelowTheStepGivesEveryStep) {
  const FrameSchedule s(interval(4e-4), 50, 1e-3);
  EXPECT_TRUE(s.interval_below_step());
  EXPECT_EQ(s.stride(), 1);
  EXPECT_EQ(s.frames(), 51);
  EXPECT_FALSE(FrameSchedule(interval(1e-3), 50, 1e-3).interval_below_step()); // T = h
}

TEST(FrameSchedule, AnOptimizationsMotionTakesAboutAHundredFrames) {
  const long long steps = 2094; // cases/slider_crank_topopt: one revolution at 20 us
  const long long cap = FrameSchedule::kOptimizationFrames;
  const FrameSchedule d(OutputSettings{}, steps, 2e-5, cap); // no output: about 100
  EXPECT_EQ(d.stride(), 21);
  EXPECT_EQ(d.frames(), static_cast<long long>(frame_steps(d, steps).size()));
  EXPECT_LE(d.frames(), cap + 2);
  const FrameSchedule e(every(10), steps, 2e-5, cap); // output: {every: 10}: 211 frames, thinned
  EXPECT_EQ(e.stride(), 21);
  EXPECT_LE(e.frames(), cap + 2);
  EXPECT_NE(e.describe().find("thinned"), std::string::npos) << e.describe();
  const FrameSchedule i(interval(3.3e-4), steps, 2e-5, cap); // an interval: thinned as well
  EXPECT_LE(i.frames(), cap + 2);
  EXPECT_EQ(i.frames(), static_cast<long long>(frame_steps(i, steps).size()));
  const FrameSchedule f(every(50), steps, 2e-5, cap); // fewer than the cap: as given
  EXPECT_EQ(f.stride(), 50);
  EXPECT_EQ(f.describe().find("thinned"), std::string::npos) << f.describe();
  EXPECT_EQ(FrameSchedule(every(10), steps, 2e-5).frames(), 211); // simulate: as given
}

TEST(MotionSizeEstimate, LinearInFramesWith24BytesPerNodeAndField) {
  flexopt::io::MotionBody b;
  b.name = "bar";
  b.layout.global_nodes = 1000;
  b.layout.global_cells = 4000;
  b.layout.nodes_per_cell = 4;
  b.layout.topology_type = "Tetrahedron";
  const std::vector<flexopt::io::MotionBody> bodies{b};
  const double e0 = flexopt::io::estimate_motion_bytes(bodies, {}, 0);
  const double e1 = flexopt::io::estimate_motion_bytes(bodies, {}, 1000);
  const double f1 = flexopt::io::estimate_motion_bytes(bodies, {{"elastic_displacement"}}, 1000);
  // The mesh: 24 bytes per node and 8 per cell node, plus two dataset headers.
  EXPECT_GE(e0, 24.0 * 1000 + 8.0 * 16000);
  EXPECT_LE(e0, 24.0 * 1000 + 8.0 * 16000 + 4096);
  // Each frame: at least the positions (24 kB here); a field adds at least its 24 kB per frame.
  EXPECT_GE((e1 - e0) / 1000, 24000.0);
  EXPECT_LE((e1 - e0) / 1000, 24000.0 + 4096);
  EXPECT_GE((f1 - e1) / 1000, 24000.0);
  EXPECT_LE((f1 - e1) / 1000, 24000.0 + 1024);
}

// design.xdmf of `optimize` (docs/output.md "Design frames"): about 100 frames by default,
// output.every when given, and the estimate's arithmetic.
TEST(DesignOutput, AboutAHundredFramesByDefault) {
  flexopt::optimize::OptimizerSettings s;
  for (const int n : {1, 12, 100, 101, 400, 1000, 1234}) {
    s.max_iterations = n;
    const int stride = flexopt::optimize::design_output_stride(s);
    const long long frames = flexopt::optimize::design_output_frames(s);
    // Iterations 1, 1 + stride, ... <= n, and the final design.
    long long counted = 1;
    for (int k = 1; k <= n; ++k) counted += (k - 1) % stride == 0;
    EXPECT_EQ(frames, counted) << n << " iterations";
    EXPECT_LE(frames, 102) << n << " iterations";
    EXPECT_GE(frames, std::min(n, 51) + 1) << n << " iterations";
  }
  s.max_iterations = 400;
  s.output_every = 7; // output.every: given, it is the stride
  EXPECT_EQ(flexopt::optimize::design_output_stride(s), 7);
  EXPECT_EQ(flexopt::optimize::design_output_frames(s), 57 + 1 + 1); // 1, 8, ..., 400; final
}

TEST(DesignOutput, A400IterationRunAt212kElementsStaysUnder1GB) {
  // The Hex8 cantilever of docs/benchmarks.md at 212k elements (128 x 64 x 26 cells).
  flexopt::io::GridLayout g;
  g.global_cells = 128LL * 64 * 26;
  g.global_nodes = 129LL * 65 * 27;
  g.nodes_per_cell = 8;
  g.topology_type = "Hexahedron";
  flexopt::optimize::OptimizerSettings s;
  s.max_iterations = 400;
  const std::vector<std::string> fields{"density", "filtered_density", "physical_density"};
  const long long frames = flexopt::optimize::design_output_frames(s);
  const double bytes = flexopt::io::estimate_xdmf_bytes(g, "design", fields, frames);
  EXPECT_LT(bytes, flexopt::optimize::kLargeDesignBytes);
  // Each frame holds at least its three float64 cell fields, and little more.
  const double e0 = flexopt::io::estimate_xdmf_bytes(g, "design", fields, 0);
  const double per_frame = (bytes - e0) / static_cast<double>(frames);
  EXPECT_GE(per_frame, 24.0 * static_cast<double>(g.global_cells));
  EXPECT_LE(per_frame, 24.0 * static_cast<double>(g.global_cells) + 4096);
  // Every iteration, as before the default changed, takes about 2 GB.
  s.output_every = 1;
  EXPECT_GT(flexopt::io::estimate_xdmf_bytes(g, "design", fields,
                                             flexopt::optimize::design_output_frames(s)),
            2e9);
}
