// PETSc TSAdjoint on a mass-spring lattice, for comparing its backward-sweep / forward-run
// time ratio with flexopt's dynamic adjoint (scripts/bench/tsadjoint.sh runs it).
//
// Model: nx x ny point masses (mass m) in the plane at rest positions X_i on a unit grid, the
// column x = 0 being fixed anchors. Springs join horizontal, vertical and (for ny > 1) both
// diagonal neighbours; spring s with stiffness k_s (the design parameters p) and rest length
// L_s pulls with tension T_s = k_s (d + c d^3), d = |e| - L_s, e = x_b - x_a, x = X + u.
// Gravity g acts along -y. First-order form, y = (u_i, v_i) per mass (4 unknowns each):
//   F(t, y, ydot) = [ udot - v ;  m vdot - f(u) - m g ] = 0,
//   f_a += T_s n_s, f_b -= T_s n_s,  n_s = e / |e|.
// Cost: Psi = u_y(tip, T) + w * int_0^T (1/N_m) sum_i |u_i|^2 dt, tip = last mass (far corner).
// Integrator: TSCN, fixed step. Gradient dPsi/dk by TSAdjointSolve (TSSetIJacobianP and a
// quadrature TS for the integral). Prints one line of "key=value" results. A backward CN step
// of TSAdjoint (PETSc 3.18) evaluates IJacobian twice (at t_{n+1} with shift 2/h, factorized
// for the transposed solve; at t_n for a transposed product), IJacobianP twice, one LU.
//
//   ts_adjoint_bench -nx 16 -ny 16 -steps 200 -dt 1e-3 [-dense] [-fd_check] [PETSc TS/SNES options]
#include <cmath>
#include <petscts.h>
#include <vector>

struct Spring {
  PetscInt a, b;    // mass indices; a = -1: anchored at (ax, ay)
  PetscReal ax, ay; // anchor position
  PetscReal rest;   // rest length L_s
};

struct Model {
  PetscInt nm, n; // masses, unknowns (4 nm)
  std::vector<Spring> springs;
  std::vector<PetscReal> X; // rest positions, 2 per mass
  std::vector<PetscReal> k; // parameters: spring stiffnesses
  PetscReal mass = 1.0, c = 10.0, g = 9.81, w = 1.0;
  PetscBool dense = PETSC_FALSE; // Jacobian storage: MATSEQDENSE or MATSEQAIJ
  int phase = 0;                 // 0: forward run, 1: adjoint sweep (for the counters)
  long nF[2] = {0, 0}, nJ[2] = {0, 0}, nJp[2] = {0, 0}; // IFunction/IJacobian/IJacobianP calls
};

// Geometry of spring s at displacement u: unit direction n, length l, extension d.
static void SpringState(const Model &M, const Spring &s, const PetscScalar *y, PetscReal n[2],
                        PetscReal &l, PetscReal &d) {
  PetscReal xa[2], xb[2];
  if (s.a < 0) {
    xa[0] = s.ax;
    xa[1] = s.ay;
  } else
    for (int q = 0; q < 2; q++) xa[q] = M.X[2 * s.a + q] + PetscRealPart(y[4 * s.a + q]);
  for (int q = 0; q < 2; q++) xb[q] = M.X[2 * s.b + q] + PetscRealPart(y[4 * s.b + q]);
  PetscReal e[2] = {xb[0] - xa[0], xb[1] - xa[1]};
  l = std::sqrt(e[0] * e[0] + e[1] * e[1]);
  n[0] = e[0] / l;
  n[1] = e[1] / l;
  d = l - s.rest;
}

// F(t,y,ydot): rows u_i: udot_i - v_i; rows v_i: m vdot_i - f_i(u) - m g_i.
static PetscErrorCode IFunction(TS, PetscReal, Vec Y, Vec Ydot, Vec F, void *ctx) {
  Model &M = *(Model *)ctx;
  const PetscScalar *y, *yd;
  PetscScalar *f;
  PetscFunctionBeginUser;
  M.nF[M.phase]++;
  PetscCall(VecGetArrayRead(Y, &y));
  PetscCall(VecGetArrayRead(Ydot, &yd));
  PetscCall(VecGetArray(F, &f));
  for (PetscInt i = 0; i < M.nm; i++) {
    for (int q = 0; q < 2; q++) {
      f[4 * i + q] = yd[4 * i + q] - y[4 * i + 2 + q];
      f[4 * i + 2 + q] = M.mass * yd[4 * i + 2 + q];
    }
    f[4 * i + 3] += M.mass * M.g; // - m g_y with g_y = -g
  }
  for (size_t j = 0; j < M.springs.size(); j++) {
    const Spring &s = M.springs[j];
    PetscReal n[2], l, d;
    SpringState(M, s, y, n, l, d);
    PetscReal T = M.k[j] * (d + M.c * d * d * d);
    for (int q = 0; q < 2; q++) { // F_v = ... - f: f_a = +T n, f_b = -T n
      if (s.a >= 0) f[4 * s.a + 2 + q] -= T * n[q];
      f[4 * s.b + 2 + q] += T * n[q];
    }
  }
  PetscCall(VecRestoreArrayRead(Y, &y));
  PetscCall(VecRestoreArrayRead(Ydot, &yd));
  PetscCall(VecRestoreArray(F, &f));
  PetscFunctionReturn(0);
}

// dF/dy + a dF/dydot:  (u,u) a I, (u,v) -I, (v,v) a m I, (v,u) -df/du, where spring s adds
// K_s = dT/dd n n^T + T/l (I - n n^T) to (v_a,u_a) and (v_b,u_b), and -K_s to (v_a,u_b), (v_b,u_a).
static PetscErrorCode IJacobian(TS, PetscReal, Vec Y, Vec, PetscReal a, Mat A, Mat P, void *ctx) {
  Model &M = *(Model *)ctx;
  const PetscScalar *y;
  PetscFunctionBeginUser;
  M.nJ[M.phase]++;
  PetscCall(MatZeroEntries(P));
  PetscCall(VecGetArrayRead(Y, &y));
  for (PetscInt i = 0; i < M.nm; i++)
    for (PetscInt q = 0; q < 2; q++) {
      PetscInt ru = 4 * i + q, rv = 4 * i + 2 + q;
      PetscScalar vals[2] = {a, -1.0}, vv = a * M.mass;
      PetscInt cols[2] = {ru, rv};
      PetscCall(MatSetValues(P, 1, &ru, 2, cols, vals, ADD_VALUES));
      PetscCall(MatSetValues(P, 1, &rv, 1, &rv, &vv, ADD_VALUES));
    }
  for (size_t j = 0; j < M.springs.size(); j++) {
    const Spring &s = M.springs[j];
    PetscReal n[2], l, d;
    SpringState(M, s, y, n, l, d);
    PetscReal T = M.k[j] * (d + M.c * d * d * d), dT = M.k[j] * (1 + 3 * M.c * d * d);
    PetscScalar K[4], mK[4];
    for (int p = 0; p < 2; p++)
      for (int q = 0; q < 2; q++) {
        K[2 * p + q] = dT * n[p] * n[q] + T / l * ((p == q) - n[p] * n[q]);
        mK[2 * p + q] = -K[2 * p + q];
      }
    PetscInt vb[2] = {4 * s.b + 2, 4 * s.b + 3}, ub[2] = {4 * s.b, 4 * s.b + 1};
    PetscCall(MatSetValues(P, 2, vb, 2, ub, K, ADD_VALUES));
    if (s.a >= 0) {
      PetscInt va[2] = {4 * s.a + 2, 4 * s.a + 3}, ua[2] = {4 * s.a, 4 * s.a + 1};
      PetscCall(MatSetValues(P, 2, va, 2, ua, K, ADD_VALUES));
      PetscCall(MatSetValues(P, 2, va, 2, ub, mK, ADD_VALUES));
      PetscCall(MatSetValues(P, 2, vb, 2, ua, mK, ADD_VALUES));
    }
  }
  PetscCall(VecRestoreArrayRead(Y, &y));
  PetscCall(MatAssemblyBegin(P, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(P, MAT_FINAL_ASSEMBLY));
  if (A != P) {
    PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  }
  PetscFunctionReturn(0);
}

// dF/dk_s (column s): rows v_a: -(d + c d^3) n, rows v_b: +(d + c d^3) n  (T = k (d + c d^3)).
static PetscErrorCode IJacobianP(TS, PetscReal, Vec Y, Vec, PetscReal, Mat A, void *ctx) {
  Model &M = *(Model *)ctx;
  const PetscScalar *y;
  PetscFunctionBeginUser;
  M.nJp[M.phase]++;
  PetscCall(VecGetArrayRead(Y, &y));
  for (PetscInt j = 0; j < (PetscInt)M.springs.size(); j++) {
    const Spring &s = M.springs[j];
    PetscReal n[2], l, d;
    SpringState(M, s, y, n, l, d);
    PetscReal t = d + M.c * d * d * d;
    for (PetscInt q = 0; q < 2; q++) {
      PetscInt rb = 4 * s.b + 2 + q;
      PetscScalar vb = t * n[q], va = -t * n[q];
      PetscCall(MatSetValues(A, 1, &rb, 1, &j, &vb, INSERT_VALUES));
      if (s.a >= 0) {
        PetscInt ra = 4 * s.a + 2 + q;
        PetscCall(MatSetValues(A, 1, &ra, 1, &j, &va, INSERT_VALUES));
      }
    }
  }
  PetscCall(VecRestoreArrayRead(Y, &y));
  PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

// Integrand r(y) = w / N_m sum_i |u_i|^2 (quadrature TS right-hand side, 1 component).
static PetscErrorCode Integrand(TS, PetscReal, Vec Y, Vec R, void *ctx) {
  Model &M = *(Model *)ctx;
  const PetscScalar *y;
  PetscScalar r = 0;
  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(Y, &y));
  for (PetscInt i = 0; i < M.nm; i++) r += y[4 * i] * y[4 * i] + y[4 * i + 1] * y[4 * i + 1];
  PetscCall(VecRestoreArrayRead(Y, &y));
  PetscCall(VecSetValue(R, 0, M.w * r / M.nm, INSERT_VALUES));
  PetscCall(VecAssemblyBegin(R));
  PetscCall(VecAssemblyEnd(R));
  PetscFunctionReturn(0);
}

// dr/dy as an n x 1 column: 2 w u_i / N_m on the u rows, 0 on the v rows.
static PetscErrorCode IntegrandJac(TS, PetscReal, Vec Y, Mat A, Mat, void *ctx) {
  Model &M = *(Model *)ctx;
  const PetscScalar *y;
  PetscScalar *col;
  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(Y, &y));
  PetscCall(MatDenseGetColumn(A, 0, &col));
  for (PetscInt i = 0; i < M.n; i++) col[i] = (i % 4 < 2) ? 2 * M.w * y[i] / M.nm : 0.0;
  PetscCall(MatDenseRestoreColumn(A, &col));
  PetscCall(VecRestoreArrayRead(Y, &y));
  PetscFunctionReturn(0);
}

// dr/dk = 0 (the integrand does not depend on the stiffnesses directly).
static PetscErrorCode IntegrandJacP(TS, PetscReal, Vec, Mat A, void *) {
  PetscFunctionBeginUser;
  PetscCall(MatZeroEntries(A));
  PetscFunctionReturn(0);
}

static void BuildModel(Model &M, PetscInt nx, PetscInt ny, PetscReal k0) {
  M.nm = nx * ny;
  M.n = 4 * M.nm;
  auto id = [&](PetscInt i, PetscInt j) { return (i - 1) * ny + j; }; // i = 1..nx
  M.X.resize(2 * M.nm);
  for (PetscInt i = 1; i <= nx; i++)
    for (PetscInt j = 0; j < ny; j++) {
      M.X[2 * id(i, j)] = i;
      M.X[2 * id(i, j) + 1] = j;
    }
  auto add = [&](PetscInt i0, PetscInt j0, PetscInt i1, PetscInt j1) {
    Spring s; // from (i0, j0) to (i1, j1), i1 >= 1
    s.a = i0 == 0 ? -1 : id(i0, j0);
    s.b = id(i1, j1);
    s.ax = i0;
    s.ay = j0;
    s.rest = std::sqrt((PetscReal)((i1 - i0) * (i1 - i0) + (j1 - j0) * (j1 - j0)));
    M.springs.push_back(s);
  };
  for (PetscInt i = 1; i <= nx; i++)
    for (PetscInt j = 0; j < ny; j++) {
      add(i - 1, j, i, j);
      if (j + 1 < ny) {
        add(i, j, i, j + 1);
        add(i - 1, j, i, j + 1);
        add(i - 1, j + 1, i, j);
      }
    }
  // stiffnesses vary a little from spring to spring so that the gradient has structure
  for (size_t s = 0; s < M.springs.size(); s++) M.k.push_back(k0 * (1.0 + 0.2 * std::sin(0.7 * s)));
}

struct Result {
  PetscReal psi = 0, fwd_s = 0, adj_s = 0;
  PetscInt steps = 0, newton = 0;
  double lu[2] = {0, 0}, solves[2] = {0, 0}; // LU factorizations and triangular solves
  std::vector<PetscReal> grad;
  char traj[64] = "none";
};

// Count of a logged PETSc event in a stage (names as -log_view prints them, up to 16 chars).
static double EventCount(PetscLogStage stage, const char *name) {
  PetscLogEvent ev;
  PetscEventPerfInfo info;
  if (PetscLogEventGetId(name, &ev) || ev < 0) return -1;
  if (PetscLogEventGetPerfInfo(stage, ev, &info)) return -1;
  return info.count;
}
// LU factorizations: MatLUFactorNum (AIJ, MUMPS) or the in-place MatLUFactor (dense).
static double Factorizations(PetscLogStage stage) {
  return EventCount(stage, "MatLUFactorNum") + EventCount(stage, "MatLUFactor");
}
static double Solves(PetscLogStage stage) {
  return EventCount(stage, "MatSolve") + EventCount(stage, "MatSolveTranspos");
}

// One forward run (and, if adjoint, the backward sweep) with a fresh TS; stiffnesses from M.k.
static PetscErrorCode Run(Model &M, PetscInt steps, PetscReal dt, bool adjoint, Result &R) {
  TS ts, quad;
  SNES snes;
  KSP ksp;
  PC pc;
  Mat J, Jp, Qj, Qp;
  Vec y, lambda, mu, cost;
  PetscInt np = M.springs.size();
  PetscLogStage stage[2];
  PetscFunctionBeginUser;
  PetscCall(PetscLogStageGetId("Forward", &stage[0]));
  PetscCall(PetscLogStageGetId("Adjoint", &stage[1]));
  if (M.dense)
    PetscCall(MatCreateSeqDense(PETSC_COMM_SELF, M.n, M.n, NULL, &J));
  else
    PetscCall(MatCreateSeqAIJ(PETSC_COMM_SELF, M.n, M.n, 20, NULL, &J));
  PetscCall(MatCreateSeqAIJ(PETSC_COMM_SELF, M.n, np, 8, NULL, &Jp));
  PetscCall(MatCreateSeqDense(PETSC_COMM_SELF, M.n, 1, NULL, &Qj));
  PetscCall(MatCreateSeqDense(PETSC_COMM_SELF, np, 1, NULL, &Qp));
  PetscCall(MatCreateVecs(J, &y, &lambda));
  PetscCall(VecCreateSeq(PETSC_COMM_SELF, np, &mu));

  PetscCall(TSCreate(PETSC_COMM_SELF, &ts));
  PetscCall(TSSetType(ts, TSCN));
  PetscCall(TSSetIFunction(ts, NULL, IFunction, &M));
  PetscCall(TSSetIJacobian(ts, J, J, IJacobian, &M));
  PetscCall(TSSetIJacobianP(ts, Jp, IJacobianP, &M));
  PetscCall(TSSetTimeStep(ts, dt));
  PetscCall(TSSetMaxSteps(ts, steps));
  PetscCall(TSSetMaxTime(ts, steps * dt * 2)); // the step count ends the run
  PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_MATCHSTEP));
  TSAdapt adapt;
  PetscCall(TSGetAdapt(ts, &adapt));
  PetscCall(TSAdaptSetType(adapt, TSADAPTNONE));
  PetscCall(TSGetSNES(ts, &snes));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPSetType(ksp, KSPPREONLY)); // direct solves only: one LU per Jacobian
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PCSetType(pc, PCLU));
  // terminal cost phi = u_y(tip): lambda(T) = dphi/dy = e_tip, mu(T) = dphi/dk = 0
  PetscCall(VecZeroEntries(lambda));
  PetscCall(VecSetValue(lambda, 4 * (M.nm - 1) + 1, 1.0, INSERT_VALUES));
  PetscCall(VecAssemblyBegin(lambda));
  PetscCall(VecAssemblyEnd(lambda));
  PetscCall(VecZeroEntries(mu));
  PetscCall(TSSetCostGradients(ts, 1, &lambda, &mu));
  PetscCall(TSCreateQuadratureTS(ts, PETSC_TRUE, &quad)); // integral accumulated forward
  PetscCall(TSSetRHSFunction(quad, NULL, Integrand, &M));
  PetscCall(TSSetRHSJacobian(quad, Qj, Qj, IntegrandJac, &M));
  PetscCall(TSSetRHSJacobianP(quad, Qp, IntegrandJacP, &M));
  if (adjoint) PetscCall(TSSetSaveTrajectory(ts));
  PetscCall(TSSetFromOptions(ts));
  PetscCall(VecZeroEntries(y));
  PetscCall(TSSetSolution(ts, y));
  PetscCall(TSSetUp(ts));
  if (adjoint) {
    TSTrajectory tj;
    const char *type;
    PetscCall(TSGetTrajectory(ts, &tj));
    PetscCall(PetscObjectGetType((PetscObject)tj, &type));
    PetscCall(PetscSNPrintf(R.traj, sizeof(R.traj), "%s", type));
  }

  double lu0 = Factorizations(stage[0]), s0 = Solves(stage[0]);
  M.phase = 0;
  PetscCall(PetscLogStagePush(stage[0]));
  double t0 = MPI_Wtime();
  PetscCall(TSSolve(ts, y));
  R.fwd_s = MPI_Wtime() - t0;
  PetscCall(PetscLogStagePop());
  R.lu[0] = Factorizations(stage[0]) - lu0;
  R.solves[0] = Solves(stage[0]) - s0;
  TSConvergedReason reason;
  PetscCall(TSGetConvergedReason(ts, &reason));
  PetscCall(TSGetStepNumber(ts, &R.steps));
  PetscCall(TSGetSNESIterations(ts, &R.newton));
  PetscCheck(reason > 0 && R.steps == steps, PETSC_COMM_SELF, PETSC_ERR_NOT_CONVERGED,
             "forward run failed: reason %d after %" PetscInt_FMT " steps", (int)reason, R.steps);
  const PetscScalar *yv, *cv;
  PetscCall(TSGetCostIntegral(ts, &cost));
  PetscCall(VecGetArrayRead(y, &yv));
  PetscCall(VecGetArrayRead(cost, &cv));
  R.psi = PetscRealPart(yv[4 * (M.nm - 1) + 1] + cv[0]);
  PetscCall(VecRestoreArrayRead(cost, &cv));
  PetscCall(VecRestoreArrayRead(y, &yv));

  if (adjoint) {
    // A lagged forward Jacobian must not leak into the backward sweep: TSAdjoint assembles its
    // matrices through SNESComputeJacobian, which honours the SNES lag. Exact Jacobians from here.
    PetscCall(SNESSetLagJacobian(snes, 1));
    PetscCall(SNESSetLagJacobianPersists(snes, PETSC_FALSE));
    PetscCall(SNESSetLagPreconditioner(snes, 1));
    PetscCall(SNESSetLagPreconditionerPersists(snes, PETSC_FALSE));
    double lu1 = Factorizations(stage[1]), s1 = Solves(stage[1]);
    M.phase = 1;
    PetscCall(PetscLogStagePush(stage[1]));
    t0 = MPI_Wtime();
    PetscCall(TSAdjointSolve(ts));
    R.adj_s = MPI_Wtime() - t0;
    PetscCall(PetscLogStagePop());
    R.lu[1] = Factorizations(stage[1]) - lu1;
    R.solves[1] = Solves(stage[1]) - s1;
    const PetscScalar *g;
    PetscCall(VecGetArrayRead(mu, &g));
    R.grad.assign(g, g + np);
    PetscCall(VecRestoreArrayRead(mu, &g));
    M.phase = 0;
  }
  PetscCall(TSDestroy(&ts));
  PetscCall(MatDestroy(&J));
  PetscCall(MatDestroy(&Jp));
  PetscCall(MatDestroy(&Qj));
  PetscCall(MatDestroy(&Qp));
  PetscCall(VecDestroy(&y));
  PetscCall(VecDestroy(&lambda));
  PetscCall(VecDestroy(&mu));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscInt nx = 10, ny = 1, steps = 2000;
  PetscReal dt = 1e-3, k0 = 1e4;
  PetscBool fd = PETSC_FALSE;
  PetscLogStage st;
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  PetscCall(PetscLogDefaultBegin()); // event counts (factorizations, solves) per stage
  PetscCall(PetscLogStageRegister("Forward", &st));
  PetscCall(PetscLogStageRegister("Adjoint", &st));
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-nx", &nx, NULL));
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-ny", &ny, NULL));
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-steps", &steps, NULL));
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-dt", &dt, NULL));
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-k", &k0, NULL));
  PetscCall(PetscOptionsGetBool(NULL, NULL, "-fd_check", &fd, NULL));
  Model M;
  PetscCall(PetscOptionsGetBool(NULL, NULL, "-dense", &M.dense, NULL));
  BuildModel(M, nx, ny, k0);
  Result R;
  PetscCall(Run(M, steps, dt, true, R));
  PetscCall(PetscPrintf(
      PETSC_COMM_SELF,
      "unknowns=%" PetscInt_FMT " params=%zu steps=%" PetscInt_FMT " trajectory=%s forward_s=%.5f "
      "adjoint_s=%.5f ratio=%.3f newton_fwd=%" PetscInt_FMT
      " F_fwd=%ld F_adj=%ld J_fwd=%ld J_adj=%ld "
      "Jp_adj=%ld lu_fwd=%.0f lu_adj=%.0f solves_fwd=%.0f solves_adj=%.0f psi=%.10g\n",
      M.n, M.springs.size(), R.steps, R.traj, R.fwd_s, R.adj_s, R.adj_s / R.fwd_s, R.newton,
      M.nF[0], M.nF[1], M.nJ[0], M.nJ[1], M.nJp[1], R.lu[0], R.lu[1], R.solves[0], R.solves[1],
      R.psi));
  if (fd) { // central differences in 3 stiffnesses against the adjoint gradient
    PetscInt np = M.springs.size(), idx[3] = {0, np / 2, np - 1};
    for (PetscInt q = 0; q < 3; q++) {
      PetscInt j = idx[q];
      PetscReal k = M.k[j], h = 1e-5 * k, psi[2];
      for (int side = 0; side < 2; side++) {
        Result Rf;
        M.k[j] = k + (side ? -h : h);
        PetscCall(Run(M, steps, dt, false, Rf));
        psi[side] = Rf.psi;
      }
      M.k[j] = k;
      PetscReal fdg = (psi[0] - psi[1]) / (2 * h);
      PetscCall(PetscPrintf(
          PETSC_COMM_SELF, "fd_check param=%" PetscInt_FMT " adjoint=%.10e fd=%.10e rel_err=%.2e\n",
          j, R.grad[j], fdg, std::fabs(R.grad[j] - fdg) / std::fabs(fdg)));
    }
  }
  PetscCall(PetscFinalize());
  return 0;
}
