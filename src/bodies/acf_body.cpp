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
  elements_ = fem::corotated_elements(mesh, material, modulus_factor);
  const std::vector<double> v = fem::element_volumes(mesh);
  const double local = material.density * std::accumulate(v.begin(), v.end(), 0.0);
  MPI_Allreduce(&local, &mass_, 1, MPI_DOUBLE, MPI_SUM, mesh.comm);
}

} // namespace flexopt::bodies
