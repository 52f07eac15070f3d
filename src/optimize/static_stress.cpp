#include "flexopt/optimize/static_stress.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"

#include <numeric>

namespace flexopt::optimize {

std::vector<PetscInt> stress_elements(const mesh::DistributedMesh &mesh,
                                      const ResponseSettings &r) {
  std::vector<PetscInt> elements;
  if (r.region.empty()) {
    elements.resize(static_cast<std::size_t>(mesh.local_elements()));
    std::iota(elements.begin(), elements.end(), PetscInt{0});
    return elements;
  }
  elements = mesh.volume_group(r.region, r.where.str() + ": stress region");
  long long n = static_cast<long long>(elements.size()), total = 0;
  MPI_Allreduce(&n, &total, 1, MPI_LONG_LONG, MPI_SUM, mesh.comm);
  if (total == 0)
    throw Error(r.where.str() + ": stress region '" + r.region + "' has no elements", true);
  return elements;
}

StaticStress::StaticStress(const mesh::DistributedMesh &mesh,
                           const fem::IsotropicMaterial &material, const ResponseSettings &r)
    : mesh_(mesh), material_(material), r_(r), elements_(stress_elements(mesh, r)),
      aggregate_(r.aggregate) {}

double StaticStress::evaluate(Vec u, const std::vector<double> &eta) {
  aggregate_.clear();
  dv_.resize(elements_.size());
  solid_.resize(elements_.size());
  Vec ul;
  const PetscScalar *ua;
  FX_PETSC(VecGhostGetLocalForm(u, &ul));
  FX_PETSC(VecGetArrayRead(ul, &ua));
  const Eigen::Vector3d xi = fem::reference_centroid(mesh_.type);
  for (std::size_t i = 0; i < elements_.size(); ++i) {
    const PetscInt e = elements_[i];
    const fem::StressMatrix S =
        fem::element_stress_matrix(mesh_.type, mesh_.element_coordinates(e), material_, xi);
    const fem::Voigt sigma = S * fem::gather_element(mesh_, e, ua);
    solid_[i] = fem::von_mises(sigma);
    dv_[i] = S.transpose() * fem::von_mises_gradient(sigma); // for the adjoint load

    aggregate_.add(eta[static_cast<std::size_t>(e)] * solid_[i], 1.0,
                   static_cast<long long>(mesh_.element_tags[static_cast<std::size_t>(e)]), -1.0);
  }
  FX_PETSC(VecRestoreArrayRead(ul, &ua));
  FX_PETSC(VecGhostRestoreLocalForm(u, &ul));
  aggregate_.reduce(mesh_.comm);
  return scale_ * aggregate_.value();
}

void StaticStress::adjoint_load(const std::vector<double> &eta, Vec rhs) const {
  fem::assemble_ghosted(rhs, [&](PetscScalar *ra) {
    for (std::size_t i = 0; i < elements_.size(); ++i) {
      const PetscInt e = elements_[i];
      const double eta_e = eta[static_cast<std::size_t>(e)];
      const double g = scale_ * aggregate_.derivative(eta_e * solid_[i], 1.0) * eta_e;
      if (g == 0.0) continue;
      const fem::ElementVector f = g * dv_[i];
      fem::add_element(mesh_, e, f.data(), ra);
    }
  });
}

void StaticStress::add_explicit(const std::vector<double> &eta, const std::vector<double> &deta,
                                double *g) const {
  for (std::size_t i = 0; i < elements_.size(); ++i) {
    const auto e = static_cast<std::size_t>(elements_[i]);
    if (deta[e] == 0.0) continue;
    g[e] += scale_ * aggregate_.derivative(eta[e] * solid_[i], 1.0) * deta[e] * solid_[i];
  }
}

long long StaticStress::global_elements() const {
  long long n = static_cast<long long>(elements_.size()), total = 0;
  MPI_Allreduce(&n, &total, 1, MPI_LONG_LONG, MPI_SUM, mesh_.comm);
  return total;
}

void StaticStress::end_iteration() {
  // Le et al. (2010), eq. 19, alpha = 1/2: c <- alpha M / R + (1 - alpha) c.
  if (r_.adaptive) scale_ = next_scale(scale_, aggregate_);
}

io::Json StaticStress::describe(const std::string &name) const {
  return describe_stress_response(name, r_, aggregate_, scale_);
}

io::Json describe_stress_response(const std::string &name, const ResponseSettings &r,
                                  const StressAggregate &a, double scale) {
  io::Json j = io::Json::object();
  j["response"] = name;
  j["body"] = r.body;
  j["aggregate"] = r.aggregate.type == StressAggregateType::Ks ? "ks" : "pnorm";
  j["value"] = scale * a.value();
  j["unscaled_value"] = a.value();
  j["scale"] = scale;
  j["peak"] = a.peak();
  j["peak_element"] = a.peak_tag();
  if (a.peak_time() >= 0) j["peak_time"] = a.peak_time();
  if (r.has_max) {
    j["max"] = r.max;
    j["peak_over_max"] = a.peak() / r.max;
  }
  return j;
}

} // namespace flexopt::optimize
