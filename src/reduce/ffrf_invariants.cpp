#include "flexopt/reduce/ffrf_invariants.hpp"

#include "flexopt/core/error.hpp"

namespace flexopt::reduce {

Eigen::Vector3d FfrfInvariants::first_moment(const Eigen::Ref<const Eigen::VectorXd> &zeta) const {
  return d0 + D * zeta;
}

Eigen::Matrix3d FfrfInvariants::second_moment(const Eigen::VectorXd &zeta) const {
  Eigen::Matrix3d S = S0;
  const int n = modes();
  for (int k = 0; k < n; ++k) {
    S += zeta(k) * (S1[static_cast<std::size_t>(k)] + S1[static_cast<std::size_t>(k)].transpose());
    for (int l = 0; l < n; ++l)
      S += zeta(k) * zeta(l) * S2[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)];
  }
  return S;
}

Eigen::Matrix3d FfrfInvariants::inertia(const Eigen::VectorXd &zeta) const {
  const Eigen::Matrix3d S = second_moment(zeta);
  return S.trace() * Eigen::Matrix3d::Identity() - S;
}

FfrfInvariants ffrf_invariants(const mesh::DistributedMesh &mesh, Mat M,
                               const std::vector<Vec> &modes, const Eigen::Vector3d &origin) {
  const int n = static_cast<int>(modes.size());
  // Vectors v_0 = ones (every component 1), v_1 = X (frame coordinates), v_{2+k} = Psi_k; for
  // every pair the 3 x 3 matrix C(v, w)_bc = sum_i v_ib (M w)_ic = sum_ij v_ib m_ij w_jc.
  Vec ones, X;
  FX_PETSC(MatCreateVecs(M, &ones, &X));
  FX_PETSC(VecSet(ones, 1.0));
  {
    PetscScalar *x;
    FX_PETSC(VecGetArray(X, &x));
    for (PetscInt i = 0; i < mesh.owned_nodes; ++i)
      for (int c = 0; c < 3; ++c)
        x[3 * i + c] =
            mesh.coordinates[3 * static_cast<std::size_t>(i) + static_cast<std::size_t>(c)] -
            origin(c);
    FX_PETSC(VecRestoreArray(X, &x));
  }
  std::vector<Vec> v{ones, X};
  v.insert(v.end(), modes.begin(), modes.end());
  const int nv = static_cast<int>(v.size());
  std::vector<Vec> Mv(static_cast<std::size_t>(nv));
  for (int a = 0; a < nv; ++a) {
    FX_PETSC(VecDuplicate(X, &Mv[static_cast<std::size_t>(a)]));
    FX_PETSC(MatMult(M, v[static_cast<std::size_t>(a)], Mv[static_cast<std::size_t>(a)]));
  }
  // Local sums for the pairs needed: (ones, X), (ones, Psi_k), (X, X), (X, Psi_k), (Psi_k, Psi_l)
  // and (ones, ones) for the mass; all 9 entries of every pair, reduced at once.
  std::vector<double> sums(static_cast<std::size_t>(nv * nv * 9), 0.0);
  std::vector<const PetscScalar *> va(static_cast<std::size_t>(nv)),
      ma(static_cast<std::size_t>(nv));
  for (int a = 0; a < nv; ++a) {
    FX_PETSC(VecGetArrayRead(v[static_cast<std::size_t>(a)], &va[static_cast<std::size_t>(a)]));
    FX_PETSC(VecGetArrayRead(Mv[static_cast<std::size_t>(a)], &ma[static_cast<std::size_t>(a)]));
  }
  for (int a = 0; a < nv; ++a)
    for (int b = 0; b < nv; ++b) {
      double *s = &sums[static_cast<std::size_t>((a * nv + b) * 9)];
      const PetscScalar *x = va[static_cast<std::size_t>(a)], *y = ma[static_cast<std::size_t>(b)];
      for (PetscInt i = 0; i < mesh.owned_nodes; ++i)
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) s[3 * r + c] += x[3 * i + r] * y[3 * i + c];
    }
  for (int a = 0; a < nv; ++a) {
    FX_PETSC(VecRestoreArrayRead(v[static_cast<std::size_t>(a)], &va[static_cast<std::size_t>(a)]));
    FX_PETSC(
        VecRestoreArrayRead(Mv[static_cast<std::size_t>(a)], &ma[static_cast<std::size_t>(a)]));
    FX_PETSC(VecDestroy(&Mv[static_cast<std::size_t>(a)]));
  }
  FX_PETSC(VecDestroy(&ones));
  FX_PETSC(VecDestroy(&X));
  MPI_Allreduce(MPI_IN_PLACE, sums.data(), static_cast<int>(sums.size()), MPI_DOUBLE, MPI_SUM,
                mesh.comm);
  auto C = [&](int a, int b) {
    Eigen::Matrix3d c;
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k)
        c(r, k) = sums[static_cast<std::size_t>((a * nv + b) * 9 + 3 * r + k)];
    return c;
  };
  FfrfInvariants inv;
  // C(ones, ones)_bc = sum_ij m_ij [b == c ... ]: every row of ones is 1, so C(ones, w)_bc =
  // sum_ij m_ij w_jc for any b; the mass is C(ones, ones)_00.
  inv.mass = C(0, 0)(0, 0);
  inv.d0 = C(0, 1).row(0).transpose();
  inv.D.resize(3, n);
  for (int k = 0; k < n; ++k) inv.D.col(k) = C(0, 2 + k).row(0).transpose();
  inv.S0 = C(1, 1);
  inv.S1.resize(static_cast<std::size_t>(n));
  inv.S2.assign(static_cast<std::size_t>(n),
                std::vector<Eigen::Matrix3d>(static_cast<std::size_t>(n)));
  for (int k = 0; k < n; ++k) {
    inv.S1[static_cast<std::size_t>(k)] = C(1, 2 + k);
    for (int l = 0; l < n; ++l)
      inv.S2[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)] = C(2 + k, 2 + l);
  }
  return inv;
}

} // namespace flexopt::reduce
