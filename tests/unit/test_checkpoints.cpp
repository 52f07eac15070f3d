// Binomial checkpointing (docs/theory.md section 9.4): the schedule's costs against an
// exhaustive dynamic program, the reversal's order and recomputation count on a counting
// chain, and the disk store's round trip.
#include "flexopt/adjoint/checkpoints.hpp"

#include <algorithm>
#include <cstdio>
#include <gtest/gtest.h>
#include <set>
#include <vector>

using namespace flexopt;
using adjoint::BinomialSchedule;
using adjoint::StepRecord;

namespace {

/// The least number of steps that visits l states backwards with c slots, every split tried.
std::vector<std::vector<long long>> exhaustive(long long L, int C) {
  std::vector<std::vector<long long>> T(static_cast<std::size_t>(C + 1),
                                        std::vector<long long>(static_cast<std::size_t>(L + 1)));
  for (int c = 0; c <= C; ++c)
    for (long long l = 1; l <= L; ++l) {
      auto &t = T[static_cast<std::size_t>(c)][static_cast<std::size_t>(l)];
      if (l == 1 || c == 0) {
        t = l * (l + 1) / 2;
        continue;
      }
      t = -1;
      for (long long k = 1; k <= l; ++k) {
        const long long v = k +
                            T[static_cast<std::size_t>(c - 1)][static_cast<std::size_t>(l - k)] +
                            T[static_cast<std::size_t>(c)][static_cast<std::size_t>(k - 1)];
        if (t < 0 || v < t) t = v;
      }
    }
  return T;
}

StepRecord record(long long j) {
  StepRecord r;
  r.state.t = static_cast<double>(j);
  r.state.q = Eigen::VectorXd::Constant(2, static_cast<double>(j));
  r.state.v = r.state.a = r.state.acc = r.state.q;
  r.state.lambda = Eigen::VectorXd::Constant(1, static_cast<double>(-j));
  return r;
}

} // namespace

TEST(BinomialSchedule, CostIsTheExhaustiveOptimum) {
  const long long L = 120;
  const int C = 5;
  const auto T = exhaustive(L, C);
  const BinomialSchedule s(L, C);
  for (int c = 0; c <= C; ++c)
    for (long long l = 1; l <= L; ++l)
      ASSERT_EQ(s.cost(l, c), T[static_cast<std::size_t>(c)][static_cast<std::size_t>(l)])
          << "l = " << l << ", c = " << c;
  // Enough slots: every state once. None: every state recomputed from the start.
  const BinomialSchedule all(50, 49);
  EXPECT_EQ(all.recomputed(), 0);
  EXPECT_EQ(BinomialSchedule(50, 0).recomputed(), 50 * 51 / 2 - 50);
}

TEST(BinomialSchedule, ReversalVisitsEveryStateOnceBackwards) {
  for (long long N : {1LL, 2LL, 7LL, 100LL, 2000LL})
    for (int slots : {0, 1, 3, 15, 31}) {
      const BinomialSchedule s(N, slots);
      auto store = adjoint::memory_store();
      // What the forward run leaves: step 0, the first descent and the last step.
      store->put(0, record(0));
      for (long long j : s.first_descent()) store->put(j, record(j));
      store->put(N, record(N));
      long long expected = N, advanced = 0;
      std::set<long long> held;
      std::size_t most = 0;
      const long long recomputed = adjoint::reverse_binomial<StepRecord>(
          s, *store,
          [&](const StepRecord &previous, long long j) {
            EXPECT_EQ(previous.state.t, static_cast<double>(j - 1));
            ++advanced;
            return record(j);
          },
          [&](long long j, const StepRecord &r) {
            EXPECT_EQ(j, expected) << "N " << N << " slots " << slots;
            EXPECT_EQ(r.state.t, static_cast<double>(j));
            EXPECT_EQ(r.state.lambda(0), static_cast<double>(-j));
            --expected;
            most = std::max<std::size_t>(
                most, static_cast<std::size_t>(store->bytes() / (8 * (1 + 4 * 2 + 1))));
          });
      EXPECT_EQ(expected, 0) << "N " << N << " slots " << slots;
      EXPECT_EQ(recomputed, advanced);
      EXPECT_EQ(recomputed, s.recomputed()) << "N " << N << " slots " << slots;
      EXPECT_LE(most, static_cast<std::size_t>(slots) + 2) << "states held at once";
    }
  const BinomialSchedule s(2000, 31);
  std::printf("2000 steps, 32 stored states: %lld recomputed steps (%.2f per step)\n",
              s.recomputed(), static_cast<double>(s.recomputed()) / 2000.0);
}

TEST(CheckpointStore, DiskKeepsRecordsBitForBit) {
  const std::string path = ::testing::TempDir() + "flexopt_checkpoints_test.h5";
  {
    auto disk = adjoint::disk_store(path);
    StepRecord r = record(7);
    r.state.q << 0.1, -1.0 / 3.0;
    r.substeps.emplace_back(record(6).state, 0.25e-3);
    r.substeps.emplace_back(r.state, 0.25e-3);
    disk->put(7, r);
    disk->put(8, record(8));
    disk->erase(8);
    const StepRecord back = disk->get(7);
    EXPECT_EQ(back.state.pack(), r.state.pack());
    EXPECT_EQ(back.state.t, r.state.t);
    ASSERT_EQ(back.substeps.size(), 2U);
    EXPECT_EQ(back.substeps[0].first.pack(), r.substeps[0].first.pack());
    EXPECT_EQ(back.substeps[1].second, 0.25e-3);
    EXPECT_THROW(disk->get(8), std::exception);
  }
  FILE *f = std::fopen(path.c_str(), "r");
  EXPECT_EQ(f, nullptr) << "the checkpoint file is removed with the store";
  if (f) std::fclose(f);
}
