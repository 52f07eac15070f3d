#pragma once
/// \file Flexible bodies in the floating frame of reference formulation with modal reduction
/// (nodal-based FFRF after Zwölfer & Gerstmayr 2020/2021; docs/theory.md section 7.3).
///
/// Coordinates q = [r, p, zeta]: the world position r of the frame origin (the centroid of the
/// body's first interface), the frame's Euler parameters p and the elastic coordinates zeta
/// of the reduction basis Psi. A node with mesh position X sits at
///   x = r + A(p) (X - origin + Psi(X) zeta).
/// Everything here is small and dense: the reduced stiffness, damping and inertia invariants
/// are computed once per reduction (in parallel, reduce/) and held on every rank.
#include "flexopt/bodies/body.hpp"
#include "flexopt/reduce/ffrf_invariants.hpp"

#include <array>
#include <vector>

namespace flexopt::bodies {

/// What an FFRF body needs from its reduction, for a basis of n vectors.
struct FfrfModel {
  reduce::FfrfInvariants invariants; ///< about the frame origin, for the basis vectors
  Matrix stiffness;                  ///< reduced stiffness K_r (n x n)
  Matrix damping;                    ///< reduced damping C_r (n x n), zero if none
  /// Centrifugal geometric stiffness per unit s_c(omega), c = xx, yy, zz, yz, xz, xy (each
  /// n x n), or empty: no geometric stiffening (linear FFRF).
  std::vector<Matrix> geometric;
  Vec3 origin{0, 0, 0}; ///< frame origin in mesh coordinates
};

class FfrfBody : public Body {
public:
  FfrfBody(std::string name, FfrfModel model);

  const char *model() const override { return "ffrf"; }
  int coordinates() const override { return 7 + n_; }
  double mass() const override { return model_.invariants.mass; }
  Vec3 origin() const override { return model_.origin; }
  const FfrfModel &data() const { return model_; }
  bool stiffening() const { return !model_.geometric.empty(); }

  /// With omega = 2 Gbar(p) p', omega' = 2 Gbar(p) p'', rho = r'' - g, rho_b = A^T rho (docs/
  /// theory.md section 7.3):
  ///   F_r = m rho + A (omega' x d + D zeta'' + omega x (omega x d) + 2 omega x D zeta')
  ///   F_w = d x rho_b + J omega' + C zeta'' + omega x J omega + 2 (tr P I - P^T) omega
  ///   F_z = D^T rho_b + C^T omega' + M_zz zeta'' - [omega^T (tr C_k I - C_k) omega]_k
  ///         + 2 [omega . sum_l zeta'_l g_lk]_k + K zeta + C_d zeta' + sum_c s_c(omega) G_c zeta
  ///   res = [F_r; 2 Gbar(p)^T F_w; F_z]
  /// with exact derivatives.
  void residual(const ConstVectorRef &q, const ConstVectorRef &v, const ConstVectorRef &a,
                const Vec3 &gravity, Eigen::Ref<Vector> res, Matrix *K, Matrix *C,
                Matrix *M) const override;
  /// bar += (d res / d model)^T mu: the residual is linear in every field of the model, so this
  /// is mu^T res with the model replaced by a direction, as a cotangent of the model's shape
  /// (docs/theory.md section 10.1; bar's fields are sized and zeroed if empty). The origin has
  /// no cotangent (geometry).
  void model_cotangent(const ConstVectorRef &q, const ConstVectorRef &v, const ConstVectorRef &a,
                       const Vec3 &gravity, const ConstVectorRef &mu, FfrfModel &bar) const;
  /// T + 1/2 zeta^T K zeta - g . (m r + A d(zeta)). The work of the geometric-stiffening
  /// forces (which depend on omega) is not a potential and is not included.
  double energy(const ConstVectorRef &q, const ConstVectorRef &v,
                const Vec3 &gravity) const override;

private:
  /// Fixed-capacity work arrays (no heap allocation per evaluation).
  using Mat9N =
      Eigen::Matrix<double, 9, Eigen::Dynamic, Eigen::ColMajor, 9, kMaxBodyCoordinates - 7>;
  using Mat3N =
      Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::ColMajor, 3, kMaxBodyCoordinates - 7>;
  /// vec C_k = vec(S1[k] + sum_l zeta_l S2[l][k]) (columns of Cv), c_k = axial(C_k) (columns of
  /// Cm) and the second moment S(zeta) = S0 + sum_k zeta_k (S1[k]^T + C_k).
  void couplings(const ConstVectorRef &z, Mat9N &Cv, Mat3N &Cm, Mat3 &S) const;

  FfrfModel model_;
  int n_ = 0;
  Matrix mzz_; ///< M_zz(k, l) = tr S2[k][l]
  // The invariants packed for matrix-vector products (the contractions with zeta, zeta' and
  // zeta'' are then single products instead of n^2 loops over 3 x 3 matrices). vec() stacks
  // the columns of a 3 x 3 matrix; g_lk = axial(S2[l][k]).
  Matrix s2_by_k_; ///< 9 x n^2, column l n + k = vec S2[l][k]; as 9n x n: (9k + e, l)
  Matrix s2_by_l_; ///< 9 x n^2, column k n + l = vec S2[l][k]; as 9n x n: (9l + e, k)
  Matrix g_by_k_;  ///< 3 x n^2, column l n + k = g_lk; as 3n x n: (3k + i, l)
  Matrix g_by_l_;  ///< 3 x n^2, column k n + l = g_lk; as 3n x n: (3l + i, k)
  Matrix s1_;      ///< 9 x n, vec S1[k]
  Matrix s1t_;     ///< 9 x n, vec S1[k]^T
  Matrix a1_;      ///< 3 x n, axial(S1[k])
};

/// axial(P) = sum a x b for P = sum a b^T: (P23 - P32, P31 - P13, P12 - P21).
inline Vec3 axial(const Mat3 &P) {
  return Vec3(P(1, 2) - P(2, 1), P(2, 0) - P(0, 2), P(0, 1) - P(1, 0));
}

} // namespace flexopt::bodies
