// Design partials of ACF bodies (docs/theory.md section 9.6) against the assembled equations:
// mu . R_d with R_d = M(w) (acc - g) + f(x; s) + f_d(x, v; s), assembled by the integrator's
// own routines (fem::add_mass with the mass factors, fem::add_corotated with damping), is
// differenced in one element's modulus factor s_k and mass factor w_k and compared with
// AcfBody::design_partials; the strain energy per element against the assembled energy and its
// modulus derivative. R_d is linear in s_k and w_k, so the central differences are exact up to
// round-off (bound 1e-9 of the term's scale).
#include "flexopt/bodies/acf_body.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/fem/assembly.hpp"
#include "test_meshes.hpp"

#include <cmath>
#include <gtest/gtest.h>

using namespace flexopt;

namespace {

double hashed(long long i, int salt) {
  unsigned long long z = static_cast<unsigned long long>(i * 7 + salt) * 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 29)) * 0xBF58476D1CE4E5B9ULL;
  return static_cast<double>(z >> 11) / 9007199254740992.0 * 2 - 1;
}

/// A ghosted mesh vector with entry (node, c) = scale * hashed(global node, c + salt): the
/// same values on every rank count. Caller destroys it.
Vec field(const mesh::DistributedMesh &m, double scale, int salt) {
  Vec v = fem::create_ghosted_vector(m);
  PetscScalar *a;
  VecGetArray(v, &a);
  for (PetscInt i = 0; i < m.owned_nodes; ++i)
    for (int c = 0; c < 3; ++c) a[3 * i + c] = scale * hashed(m.node_start + i, 10 * c + salt);
  VecRestoreArray(v, &a);
  VecGhostUpdateBegin(v, INSERT_VALUES, SCATTER_FORWARD);
  VecGhostUpdateEnd(v, INSERT_VALUES, SCATTER_FORWARD);
  return v;
}

} // namespace

TEST(AcfDesign, ElementPartialsAreThoseOfTheAssembledEquations) {
  const mesh::DistributedMesh m = test_support::load_test_mesh("beam.geo", 0.05, 1);
  const fem::IsotropicMaterial steel{2.1e11, 0.3, 7850};
  const double beta = 2e-4; // stiffness-proportional damping [s]
  bodies::AcfBody body("beam", m, steel, {}, beta);
  const auto ne = static_cast<std::size_t>(m.local_elements());
  std::vector<double> s(ne), w(ne);
  for (std::size_t e = 0; e < ne; ++e) {
    const auto tag = static_cast<long long>(m.element_tags[e]);
    s[e] = 0.2 + 0.8 * std::abs(hashed(tag, 1));
    w[e] = 0.2 + 0.8 * std::abs(hashed(tag, 2));
  }
  const Eigen::Vector3d g(0.5, -9.81, 0.2);
  Vec u = field(m, 2e-3, 3), v = field(m, 0.3, 4), acc = field(m, 5.0, 5), mu = field(m, 1.0, 6);
  Vec ul, vl, al, ml;
  VecGhostGetLocalForm(u, &ul);
  VecGhostGetLocalForm(v, &vl);
  VecGhostGetLocalForm(acc, &al);
  VecGhostGetLocalForm(mu, &ml);
  const PetscScalar *ua, *va, *aa, *ma;
  VecGetArrayRead(ul, &ua);
  VecGetArrayRead(vl, &va);
  VecGetArrayRead(al, &aa);
  VecGetArrayRead(ml, &ma);
  Vec F = fem::create_ghosted_vector(m), G = fem::create_ghosted_vector(m), R;
  VecDuplicate(F, &R);
  Mat M = fem::create_matrix(m);
  // mu . R_d at the factors (s, w), assembled: its stiffness part (which = 0) or its mass part
  // (which = 1) alone, each linear in its factor (apart, the elastic forces of 1e8 N would
  // drown the mass part's differences in round-off).
  auto residual = [&](const std::vector<double> &sf, const std::vector<double> &wf, int which) {
    body.set_factors(sf, wf);
    VecZeroEntries(F);
    std::string failure;
    const fem::CorotatedDamping damping{va, beta, 0};
    fem::add_corotated(m, body.elements(), ua, {}, F, nullptr, failure, &damping);
    EXPECT_TRUE(failure.empty()) << failure;
    VecAssemblyBegin(F);
    VecAssemblyEnd(F);
    MatZeroEntries(M);
    fem::add_mass(m, steel.density, wf, {}, M);
    MatAssemblyBegin(M, MAT_FINAL_ASSEMBLY);
    MatAssemblyEnd(M, MAT_FINAL_ASSEMBLY);
    VecCopy(acc, G);
    PetscScalar *ga;
    VecGetArray(G, &ga);
    for (PetscInt i = 0; i < m.owned_nodes; ++i)
      for (int c = 0; c < 3; ++c) ga[3 * i + c] -= g(c);
    VecRestoreArray(G, &ga);
    MatMult(M, G, R);
    if (which == 0) VecCopy(F, R);
    PetscScalar dot;
    VecDot(R, mu, &dot);
    return dot;
  };
  body.set_factors(s, w);
  std::vector<std::vector<double>> d_modulus, d_mass;
  body.design_partials(ua, va, aa, {ma}, g, d_modulus, d_mass);
  // A few elements by global number, differenced on every rank together.
  for (PetscInt pick : {0, 7, 40}) {
    const PetscInt global = pick % m.global_elements;
    const PetscInt local = global - m.element_start;
    const bool mine = local >= 0 && local < m.local_elements();
    for (int which = 0; which < 2; ++which) {
      std::vector<double> sp = s, sm = s, wp = w, wm = w;
      const double delta = 1e-3;
      if (mine) {
        auto &p = which == 0 ? sp : wp;
        auto &q = which == 0 ? sm : wm;
        p[static_cast<std::size_t>(local)] += delta;
        q[static_cast<std::size_t>(local)] -= delta;
      }
      const double fd = (residual(sp, wp, which) - residual(sm, wm, which)) / (2 * delta);
      double analytic =
          mine ? (which == 0 ? d_modulus : d_mass)[0][static_cast<std::size_t>(local)] : 0;
      MPI_Allreduce(MPI_IN_PLACE, &analytic, 1, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
      EXPECT_NEAR(analytic, fd, 1e-9 * std::max(std::abs(fd), 1e-6))
          << (which == 0 ? "modulus" : "mass") << " factor of element " << global;
    }
  }
  // The strain energy: sum of element energies = the assembled energy; d/ds_e = U_e / s_e.
  body.set_factors(s, w);
  const std::vector<double> U = body.element_energies(ua);
  double local = 0;
  for (double x : U) local += x;
  double total = 0;
  MPI_Allreduce(&local, &total, 1, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
  VecZeroEntries(F);
  std::string failure;
  const double assembled =
      fem::reduce_corotated(PETSC_COMM_WORLD,
                            fem::add_corotated(m, body.elements(), ua, {}, F, nullptr, failure),
                            failure)
          .energy;
  EXPECT_NEAR(total, assembled, 1e-12 * assembled);
  EXPECT_GT(assembled, 0);
  VecRestoreArrayRead(ul, &ua);
  VecRestoreArrayRead(vl, &va);
  VecRestoreArrayRead(al, &aa);
  VecRestoreArrayRead(ml, &ma);
  VecGhostRestoreLocalForm(u, &ul);
  VecGhostRestoreLocalForm(v, &vl);
  VecGhostRestoreLocalForm(acc, &al);
  VecGhostRestoreLocalForm(mu, &ml);
  for (Vec *x : {&u, &v, &acc, &mu, &F, &G, &R}) VecDestroy(x);
  MatDestroy(&M);
}
