// The initial elastic state of an FFRF body (reduce/field_projection.hpp, docs/theory.md
// section 7.6): fields projected onto the M-orthonormal basis of meshes/bar.geo (frame at "pin",
// static modes of "tip", 4 fixed-interface modes), on 1 and 2 ranks:
//  - a basis vector's own field projects to the unit vector, with nothing left out;
//  - ||u||_M^2 of a unit rigid translation is the body's mass;
//  - projecting the basis field of those coordinates again returns them (a projection is
//    idempotent), and the part left out, (1 - |zeta|^2 / u^T M u)^(1/2), is Pythagoras.
#include "flexopt/core/context.hpp"
#include "flexopt/fem/element.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/reduce/field_projection.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"
#include "test_meshes.hpp"

#include <cmath>
#include <gtest/gtest.h>
#include <map>
#include <tuple>

using namespace flexopt;

namespace {

const fem::IsotropicMaterial kAluminium{7.0e10, 0.33, 2700};

/// The owned nodes' values of the field sum_k c_k Psi_k, looked up by node coordinates (the
/// projection evaluates its field at the owned nodes only).
struct BasisField {
  std::map<std::tuple<double, double, double>, Eigen::Vector3d> at;
  BasisField(const mesh::DistributedMesh &m, const reduce::FlexibleReduction &r,
             const Eigen::VectorXd &c) {
    const Eigen::VectorXd values = reduce::owned_basis_values(r, m.owned_nodes) * c;
    for (PetscInt i = 0; i < m.owned_nodes; ++i) {
      const auto k = static_cast<std::size_t>(3 * i);
      at[{m.coordinates[k], m.coordinates[k + 1], m.coordinates[k + 2]}] = values.segment<3>(3 * i);
    }
  }
  Eigen::Vector3d operator()(const Eigen::Vector3d &x) const {
    return at.at({x.x(), x.y(), x.z()});
  }
};

} // namespace

TEST(FieldProjection, BasisVectorsAndRigidFields) {
  const mesh::DistributedMesh m = test_support::load_test_mesh("bar.geo", 0.05, 1);
  reduce::FlexibleReduction red;
  reduce::reduce_flexible_body(m, kAluminium, {"pin", "tip"}, 4, false, red);
  const int n = red.size();
  ASSERT_EQ(n, 10);

  // Psi_k itself: zeta = e_k. Psi^T M Psi = I holds to the eigensolver's accuracy (~1e-12), and
  // the part left out is the square root of a difference of nearly equal numbers: ~1e-6.
  for (int k : {0, 5, 9}) {
    const reduce::FieldProjection p = reduce::project_field(
        m, kAluminium.density, red, BasisField(m, red, Eigen::VectorXd::Unit(n, k)));
    EXPECT_LT((p.coordinates - Eigen::VectorXd::Unit(n, k)).norm(), 1e-10) << "basis vector " << k;
    EXPECT_NEAR(p.norm, 1.0, 1e-10);
    EXPECT_LT(p.residual, 1e-5);
  }

  // A unit translation along y: u^T M u = the mass, rho L b^2, as the consistent mass matrix
  // integrates the density exactly.
  const double mass = kAluminium.density * 1.0 * 0.02 * 0.02;
  const reduce::FieldProjection t = reduce::project_field(
      m, kAluminium.density, red, [](const Eigen::Vector3d &) { return Eigen::Vector3d(0, 1, 0); });
  EXPECT_NEAR(t.norm * t.norm, mass, 1e-10 * mass);
  // The basis keeps the pin face fixed, so a rigid translation is partly outside it; the static
  // mode moving the tip face along y and the bending modes carry the rest.
  EXPECT_GT(t.residual, 0.05);
  EXPECT_LT(t.residual, 1.0);
  // Pythagoras: |zeta|^2 + (left out)^2 = u^T M u.
  EXPECT_NEAR(t.coordinates.squaredNorm() + std::pow(t.residual * t.norm, 2), mass, 1e-12 * mass);
  // Idempotent: the projection of Psi zeta is zeta.
  const reduce::FieldProjection again =
      reduce::project_field(m, kAluminium.density, red, BasisField(m, red, t.coordinates));
  EXPECT_LT((again.coordinates - t.coordinates).norm(), 1e-10 * t.coordinates.norm());
}
