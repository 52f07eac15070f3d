#pragma once
/// \file A stress response on an FFRF body in a dynamic analysis (docs/theory.md section 10.3):
/// the body's stress shapes (once per reduction), its elastic coordinates recorded at every main
/// step, the space-time aggregate of the relaxed von Mises stress after the forward run, and
/// what the adjoint needs: dR/dzeta_n per step, the stress shapes' cotangent and the explicit
/// dR/d(rho) of the relaxation.
#include "flexopt/fem/element.hpp"
#include "flexopt/io/json.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/optimize/response.hpp"
#include "flexopt/optimize/stress_aggregate.hpp"

#include <Eigen/Dense>
#include <petscvec.h>
#include <vector>

namespace flexopt::adjoint {

class FfrfStress {
public:
  /// The response r on the body meshed as `mesh` (which must outlive this) of material
  /// `material`, the elements of r.region (all when empty). Collective.
  FfrfStress(const optimize::ResponseSettings &r, const mesh::DistributedMesh &mesh,
             const fem::IsotropicMaterial &material);
  /// The stress shapes of the body's current basis (after each of its reductions). Collective.
  void set_basis(const std::vector<Vec> &basis);
  /// Forgets the recorded steps (a new forward run).
  void clear() { zeta_.clear(); }
  /// The body's elastic coordinates at the next main step.
  void record(const Eigen::VectorXd &zeta) { zeta_.push_back(zeta); }
  /// After the forward run of `steps` main steps of size h: the aggregate R over every element
  /// and step with relaxation factors eta (per local element of the body; empty: 1), and with
  /// `gradients` dR/dzeta_n, the shapes' cotangent and the explicit gradient (with deta).
  /// Returns R. Collective.
  double finish(double h, const std::vector<double> &eta, const std::vector<double> &deta,
                bool gradients);
  /// dR/dzeta at main step n (empty vector: none recorded).
  Eigen::VectorXd dzeta(std::size_t n) const { return dzeta_.col(static_cast<Eigen::Index>(n)); }
  /// The stress shapes' cotangent (6 |elements| x m, the shapes' layout) and its adjoint into
  /// the basis vectors' cotangents `out` (one per basis vector). Collective.
  void add_basis_cotangent(const std::vector<Vec> &out) const;
  /// The explicit dR/d(physical density) of every local element (sum_n g eta' v).
  const std::vector<double> &explicit_gradient() const { return explicit_; }
  /// {"response", "aggregate", "value", "peak", "peak_element", "peak_time", ...}.
  io::Json describe(const std::string &name) const;
  const optimize::StressAggregate &aggregate() const { return aggregate_; }
  /// Adaptive normalization (docs/theory.md 5.1): the value and its derivatives are c R; c
  /// follows the true peak after each optimization iteration (no-op without it).
  void end_iteration();
  double scale() const { return scale_; }
  void set_scale(double c) { scale_ = c; }

private:
  /// dR/dzeta_n, the shapes' cotangent and the explicit gradient of the last aggregate, from
  /// the recorded coordinates Z (m x steps). Collective.
  void adjoint_pieces(const Eigen::MatrixXd &Z, const std::vector<double> &eta,
                      const std::vector<double> &deta);
  optimize::ResponseSettings r_;
  const mesh::DistributedMesh &mesh_;
  fem::IsotropicMaterial material_;
  std::vector<PetscInt> elements_;
  Eigen::MatrixXd shapes_;            ///< T: 6 |elements| x m
  std::vector<Eigen::VectorXd> zeta_; ///< per main step
  optimize::StressAggregate aggregate_;
  Eigen::MatrixXd dzeta_;           ///< m x (steps + 1)
  Eigen::MatrixXd shape_cotangent_; ///< Tbar, the shapes' layout
  std::vector<double> explicit_;    ///< per local element
  double scale_ = 1.0;              ///< adaptive normalization c
};

} // namespace flexopt::adjoint
