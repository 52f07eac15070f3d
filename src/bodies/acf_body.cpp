#include "flexopt/bodies/acf_body.hpp"

#include "flexopt/core/error.hpp"

#include <numeric>
#include <utility>

namespace flexopt::bodies {

AcfBody::AcfBody(std::string name, const mesh::DistributedMesh &mesh,
                 const fem::IsotropicMaterial &material, const std::vector<double> &modulus_factor,
                 double damping)
    : name_(std::move(name)), mesh_(mesh), material_(material), damping_(damping) {
  if (!(damping >= 0))
    throw Error("ACF body '" + name_ + "': the damping coefficient must not be negative");
  set_factors(modulus_factor, {});
}

void AcfBody::set_factors(const std::vector<double> &modulus_factor,
                          const std::vector<double> &mass_factor) {
  const auto n = static_cast<std::size_t>(mesh_.local_elements());
  if ((!modulus_factor.empty() && modulus_factor.size() != n) ||
      (!mass_factor.empty() && mass_factor.size() != n))
    throw Error("ACF body '" + name_ + "': one factor per local element is needed");
  modulus_factor_ = modulus_factor;
  mass_factor_ = mass_factor;
  elements_ = fem::corotated_elements(mesh_, material_, modulus_factor_);
  const std::vector<double> v = fem::element_volumes(mesh_);
  double local = 0;
  for (std::size_t e = 0; e < n; ++e)
    local += v[e] * (mass_factor_.empty() ? 1.0 : mass_factor_[e]);
  local *= material_.density;
  MPI_Allreduce(&local, &mass_, 1, MPI_DOUBLE, MPI_SUM, mesh_.comm);
}

fem::ElementCoords AcfBody::positions(PetscInt e, const double *u) const {
  const fem::ElementVector ue = fem::gather_element(mesh_, e, u);
  fem::ElementCoords x = elements_[static_cast<std::size_t>(e)].X;
  for (int a = 0; a < x.rows(); ++a) x.row(a) += ue.segment<3>(3 * a).transpose();
  return x;
}

void AcfBody::design_partials(const double *u, const double *v, const double *acc,
                              const std::vector<const double *> &mu, const Eigen::Vector3d &gravity,
                              std::vector<std::vector<double>> &d_modulus,
                              std::vector<std::vector<double>> &d_mass) const {
  const auto n = static_cast<std::size_t>(mesh_.local_elements());
  d_modulus.assign(mu.size(), std::vector<double>(n, 0.0));
  d_mass.assign(mu.size(), std::vector<double>(n, 0.0));
  fem::ElementVector f, fd, Ma;
  for (std::size_t k = 0; k < n; ++k) {
    const auto e = static_cast<PetscInt>(k);
    const fem::CorotatedElement &ce = elements_[k];
    const fem::ElementCoords x = positions(e, u);
    fem::corotated_state(ce, x, &f, nullptr);
    if (v && damping_ > 0) {
      fem::corotated_damping(ce, x, fem::gather_element(mesh_, e, v), damping_, &fd, nullptr,
                             nullptr);
      f += fd;
    }
    const double s = modulus_factor_.empty() ? 1.0 : modulus_factor_[k];
    f /= s;
    // M0_e (acc_e - g): the consistent mass at the material density (section 9.6).
    fem::ElementVector a = fem::gather_element(mesh_, e, acc);
    for (int b = 0; b < ce.nodes(); ++b) a.segment<3>(3 * b) -= gravity;
    Ma = fem::element_mass(ce.type, ce.X, material_.density) * a;
    for (std::size_t r = 0; r < mu.size(); ++r) {
      const fem::ElementVector me = fem::gather_element(mesh_, e, mu[r]);
      d_modulus[r][k] = me.dot(f);
      d_mass[r][k] = me.dot(Ma);
    }
  }
}

std::vector<double> AcfBody::element_energies(const double *u, double *force) const {
  const PetscInt n = mesh_.local_elements();
  std::vector<double> out(static_cast<std::size_t>(n));
  fem::ElementVector f;
  const int npe = mesh_.nodes_per_element();
  for (PetscInt e = 0; e < n; ++e) {
    const fem::CorotatedElement &ce = elements_[static_cast<std::size_t>(e)];
    out[static_cast<std::size_t>(e)] =
        fem::corotated_state(ce, positions(e, u), force ? &f : nullptr, nullptr);
    if (force)
      for (int a = 0; a < npe; ++a) {
        const PetscInt node = mesh_.connectivity[static_cast<std::size_t>(e * npe + a)];
        for (int c = 0; c < 3; ++c) force[3 * node + c] += f(3 * a + c);
      }
  }
  return out;
}

} // namespace flexopt::bodies
