#pragma once
/// \file Rigid bodies: mass properties integrated from the FE mass matrix of the body's mesh,
/// interface points, and the inertial terms of the equations of motion in Euler parameters
/// (docs/theory.md section 6.2).
#include "flexopt/bodies/body.hpp"
#include "flexopt/mesh/mesh_data.hpp"

#include <string>

namespace flexopt::bodies {

/// Mass, centre of mass and inertia tensor about the centre of mass, in the body (mesh)
/// frame. From the consistent FE mass matrix M (scalar per node pair, M_ab = int rho N_a N_b):
/// m = sum_ab M_ab, m c = sum_ab M_ab X_b, S = sum_ab M_ab X_a X_b^T, J_o = tr(S) I - S,
/// J_c = J_o - m (|c|^2 I - c c^T). A flexible body of the same mesh carries the same inertia.
struct MassProperties {
  double mass = 0;
  Vec3 center{0, 0, 0};
  Mat3 inertia = Mat3::Zero();
};

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
/// q = [r (centre of mass, world), p (Euler parameters)] (7 numbers), velocities v = q' and
/// accelerations a = q'':
///
///   f_r = m a_r
///   f_p = 4 Gbar(p)^T J Gbar(p) a_p + 8 Gbar(v_p)^T J Gbar(p) v_p
///
/// with J the inertia about the centre of mass in body axes. The mass matrix
/// M = diag(m I, 4 Gbar^T J Gbar) is singular along p; the constraint |p|^2 = 1 removes that
/// direction (section 6.2).
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

private:
  MassProperties props_;
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
