#pragma once
/// \file A stress response on an FFRF body in a dynamic analysis (docs/theory.md section 10.3):
/// the body's stress shapes (once per reduction), its elastic coordinates recorded at every main
/// step, the space-time aggregate of the relaxed von Mises stress after the forward run, and
/// what the adjoint needs: dR/dzeta_n per step, the stress shapes' cotangent and the explicit
/// dR/d(rho) of the relaxation.
#include "flexopt/adjoint/body_stress.hpp"

#include <Eigen/Dense>
#include <petscvec.h>
#include <vector>

namespace flexopt::adjoint {

class FfrfStress : public BodyStress {
public:
  /// The response r on the body meshed as `mesh` (which must outlive this) of material
  /// `material`, the elements of r.region (all when empty). Collective.
  FfrfStress(const optimize::ResponseSettings &r, const mesh::DistributedMesh &mesh,
             const fem::IsotropicMaterial &material);
  /// The stress shapes of the body's current basis (after each of its reductions). Collective.
  void set_basis(const std::vector<Vec> &basis);
  void clear() override { zeta_.clear(); }
  /// The body's elastic coordinates at the next main step.
  void record(const Eigen::VectorXd &zeta) { zeta_.push_back(zeta); }
  /// Also dR/dzeta_n and the shapes' cotangent with `gradients`.
  double finish(double h, const std::vector<double> &eta, const std::vector<double> &deta,
                bool gradients) override;
  /// dR/dzeta at main step n (empty vector: none recorded).
  Eigen::VectorXd dzeta(std::size_t n) const { return dzeta_.col(static_cast<Eigen::Index>(n)); }
  /// The stress shapes' cotangent (6 |elements| x m, the shapes' layout) and its adjoint into
  /// the basis vectors' cotangents `out` (one per basis vector). Collective.
  void add_basis_cotangent(const std::vector<Vec> &out) const;

private:
  /// dR/dzeta_n, the shapes' cotangent and the explicit gradient of the last aggregate, from
  /// the recorded coordinates Z (m x steps). Collective.
  void adjoint_pieces(const Eigen::MatrixXd &Z, const std::vector<double> &eta,
                      const std::vector<double> &deta);
  Eigen::MatrixXd shapes_;            ///< T: 6 |elements| x m
  std::vector<Eigen::VectorXd> zeta_; ///< per main step
  Eigen::MatrixXd dzeta_;             ///< m x (steps + 1)
  Eigen::MatrixXd shape_cotangent_;   ///< Tbar, the shapes' layout
};

} // namespace flexopt::adjoint
