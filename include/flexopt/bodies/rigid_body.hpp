#pragma once
/// \file Rigid bodies: mass properties integrated from the FE mass matrix of the body's mesh,
/// interface points, and the inertial terms of the equations of motion in Euler parameters
/// (docs/theory.md section 6.2).
#include "flexopt/bodies/body.hpp"
#include "flexopt/fem/element.hpp"
#include "flexopt/mesh/mesh_data.hpp"

#include <string>

namespace flexopt::bodies {

/// Mass, centre of mass and inertia tensor about the centre of mass, in the body (mesh)
/// frame. From the consistent FE mass matrix M (scalar per node pair, M_ab = int rho N_a N_b):
/// m = sum_ab M_ab, m c = sum_ab M_ab X_b, S = sum_ab M_ab X_a X_b^T, J_o = tr(S) I - S,
/// J_c = J_o - m (|c|^2 I - c c^T). A flexible body of the same mesh carries the same inertia.
struct MassProperties {
  double mass = 0;
  /// The body's reference point o (mesh coordinates): the centre of mass, unless `first` is
  /// non-zero (a design body, docs/theory.md section 9.1).
  Vec3 center{0, 0, 0};
  Mat3 inertia = Mat3::Zero(); ///< about `center`, body axes
  /// First moment of mass about `center`: sum m_i (X_i - center); zero when `center` is the
  /// centre of mass.
  Vec3 first{0, 0, 0};
};

/// The ten mass parameters theta = (m, S, J_xx, J_yy, J_zz, J_xy, J_yz, J_xz) of a body or an
/// element about a reference point (docs/theory.md section 9.1), linear in the masses.
using MassParameters = Eigen::Matrix<double, 10, 1>;
MassParameters to_parameters(const MassProperties &p);
/// The properties with reference point `reference` whose parameters are theta.
MassProperties from_parameters(const MassParameters &theta, const Vec3 &reference);
/// The parameters about `reference` of each element of `X` (one element's node coordinates per
/// ElementCoords; all elements of type `type`) of solid density `density` [kg/m^3], as in
/// mass_properties() element by element.
MassParameters element_mass_parameters(fem::ElementType type, const fem::ElementCoords &X,
                                       double density, const Vec3 &reference);

/// Mass properties of a whole mesh of density `density` [kg/m^3]. Not collective (call where
/// the MeshData lives, rank 0, and broadcast: every rank then holds bitwise the same values).
MassProperties mass_properties(const mesh::MeshData &mesh, double density);

/// Area-weighted centroid of a physical surface of the mesh (body frame) and its area.
/// Throws flexopt::Error if the surface does not exist.
struct SurfaceCentroid {
  Vec3 centroid{0, 0, 0};
  double area = 0;
};
SurfaceCentroid surface_centroid(const mesh::MeshData &mesh, const std::string &surface);

/// The inertial part of a rigid body's equations of motion, for its coordinates
/// q = [r (the reference point o, world), p (Euler parameters)] (7 numbers), velocities v = q'
/// and accelerations a = q'':
///
///   f_r = m a_r + A(p) (alpha x S + omega x (omega x S))
///   f_p = 4 Gbar(p)^T J Gbar(p) a_p + 8 Gbar(v_p)^T J Gbar(p) v_p + 2 Gbar^T (S x A^T a_r)
///
/// with J the inertia about o in body axes, S the first moment about o (zero when o is the
/// centre of mass: section 6.2), omega = 2 Gbar v_p, alpha = 2 Gbar a_p (section 9.1). The mass
/// matrix is singular along p; the constraint |p|^2 = 1 removes that direction.
class RigidBody : public Body {
public:
  static constexpr int kCoordinates = 7;
  using Vec7 = Eigen::Matrix<double, 7, 1>;
  using Mat7 = Eigen::Matrix<double, 7, 7>;

  RigidBody(std::string name, const MassProperties &props);

  const char *model() const override { return "rigid"; }
  int coordinates() const override { return kCoordinates; }
  double mass() const override { return props_.mass; }
  Vec3 origin() const override { return props_.center; }
  const Vec3 &center() const { return props_.center; }
  const Mat3 &inertia() const { return props_.inertia; }
  const MassProperties &properties() const { return props_; }
  /// The centre of mass in mesh coordinates: center() + S / m.
  Vec3 center_of_mass() const;

  /// f(q, v, a) and its derivatives d f/dq, d f/dv, d f/da (= M(q)). Any output may be null.
  void inertial_force(const Vec7 &q, const Vec7 &v, const Vec7 &a, Vec7 *f, Mat7 *df_dq,
                      Mat7 *df_dv, Mat7 *mass_matrix) const;
  /// Kinetic energy 1/2 m |v_r|^2 + 1/2 w^T J w, w = 2 Gbar(p) v_p.
  double kinetic_energy(const Vec7 &q, const Vec7 &v) const;

  /// inertial_force() minus the weight m g on r.
  void residual(const ConstVectorRef &q, const ConstVectorRef &v, const ConstVectorRef &a,
                const Vec3 &gravity, Eigen::Ref<Vector> res, Matrix *K, Matrix *C,
                Matrix *M) const override;
  double energy(const ConstVectorRef &q, const ConstVectorRef &v,
                const Vec3 &gravity) const override;

  /// d res / d theta (7 x 10) at (q, v, a): the residual is linear and homogeneous in the mass
  /// parameters, so column k is the residual of this body with theta = e_k (section 9.1).
  Eigen::Matrix<double, 7, 10> parameter_jacobian(const Vec7 &q, const Vec7 &v, const Vec7 &a,
                                                  const Vec3 &gravity) const;

private:
  MassProperties props_;
  bool offset_ = false; ///< first moment non-zero: the terms of section 9.1
};

} // namespace flexopt::bodies

namespace flexopt::bodies {

/// The interface node of an ACF body's interface (docs/theory.md section 8.2): a massless rigid
/// body with its reference point at the interface centroid c_I (mesh coordinates) and the mesh
/// axes, held by the ties to the body's surface nodes. Joints, drivers and loads attach to it
/// as to a rigid body.
class InterfaceNode : public RigidBody {
public:
  InterfaceNode(std::string name, const Vec3 &centroid)
      : RigidBody(std::move(name), MassProperties{0.0, centroid, Mat3::Zero()}) {}
  const char *model() const override { return "interface"; }
};

} // namespace flexopt::bodies
