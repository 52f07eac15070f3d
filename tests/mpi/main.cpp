// GoogleTest main for tests that run under mpirun: PETSc/SLEPc initialised once; only rank 0
// prints test progress, but a failure on any rank makes that rank (and mpirun) exit non-zero.
#include "flexopt/core/context.hpp"

#include <gtest/gtest.h>

int main(int argc, char **argv) {
  ::testing::InitGoogleTest(&argc, argv);
  flexopt::Context ctx(&argc, &argv, nullptr);
  if (ctx.rank() != 0) {
    auto &listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  int status = RUN_ALL_TESTS();
  int global = 0;
  MPI_Allreduce(&status, &global, 1, MPI_INT, MPI_MAX, ctx.comm());
  return global;
}
