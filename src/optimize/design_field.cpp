#include "flexopt/optimize/design_field.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/optimize/design_problem.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace flexopt::optimize {

Evaluation::~Evaluation() {
  VecDestroy(&d_objective);
  for (Vec &v : d_constraints) VecDestroy(&v);
}

DesignField::DesignField(const mesh::DistributedMesh &m, const DesignSettings &d)
    : mesh_(m), spec_(d) {
  const auto &region = m.volume_group(d.region, d.region_where.str() + ": design.region");
  is_design_.assign(static_cast<std::size_t>(m.local_elements()), 0);
  for (PetscInt e : region) is_design_[static_cast<std::size_t>(e)] = 1;
  for (PetscInt e = 0; e < m.local_elements(); ++e)
    if (is_design_[static_cast<std::size_t>(e)]) {
      design_elements_.push_back(e);
      design_tags_.push_back(m.element_tags[static_cast<std::size_t>(e)]);
    }
  PetscInt n_local = static_cast<PetscInt>(design_elements_.size());
  MPI_Allreduce(&n_local, &global_design_, 1, MPIU_INT, MPI_SUM, m.comm);
  if (global_design_ == 0)
    throw Error(d.region_where.str() + ": design.region '" + d.region + "' has no elements", true);
  volume_ = fem::element_volumes(m);
  double local_volume = 0;
  for (PetscInt e : design_elements_) local_volume += volume_[static_cast<std::size_t>(e)];
  MPI_Allreduce(&local_volume, &design_volume_, 1, MPI_DOUBLE, MPI_SUM, m.comm);

  if (spec_.filter_radius == 0)
    spec_.filter_radius =
        default_filter_radius(m, design_elements_, spec_.filter_type, &default_edge_);
  filter_ = create_density_filter(m, spec_.filter_type, spec_.filter_radius);
  rho_ = filter_->create_element_vector();
  FX_PETSC(VecDuplicate(rho_, &filtered_));
  FX_PETSC(VecDuplicate(rho_, &physical_));
  FX_PETSC(VecDuplicate(rho_, &work_));
  if (!d.beta.empty()) beta_ = d.beta.front();
}

double DesignField::default_filter_radius(const mesh::DistributedMesh &m,
                                          const std::vector<PetscInt> &elements, FilterType type,
                                          double *mean_edge) {
  // The edges between corner nodes: 6 of a tet, 12 of a hexahedron (Gmsh's node order).
  static const int tet_edges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}};
  static const int hex_edges[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                       {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  const bool hex = fem::corner_nodes(m.type) == 8;
  const int(*edges)[2] = hex ? hex_edges : tet_edges;
  const int n_edges = hex ? 12 : 6;
  const int npe = m.nodes_per_element();
  double sum[2] = {0, 0}; // edge lengths, edges
  for (PetscInt e : elements) {
    const PetscInt *node = &m.connectivity[static_cast<std::size_t>(e * npe)];
    for (int k = 0; k < n_edges; ++k) {
      const double *a = &m.coordinates[static_cast<std::size_t>(3 * node[edges[k][0]])];
      const double *b = &m.coordinates[static_cast<std::size_t>(3 * node[edges[k][1]])];
      sum[0] += std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                          (a[2] - b[2]) * (a[2] - b[2]));
    }
    sum[1] += n_edges;
  }
  MPI_Allreduce(MPI_IN_PLACE, sum, 2, MPI_DOUBLE, MPI_SUM, m.comm);
  const double h = sum[0] / sum[1];
  if (mean_edge) *mean_edge = h;
  const double cone = 2.5 * h;
  return type == FilterType::Cone ? cone : cone / (2 * std::sqrt(3.0));
}

std::string DesignField::filter_description() const {
  std::string s = filter_->describe();
  if (default_edge_ > 0) {
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  " (design.filter.radius not given: %s2.5 x the mean element edge %.3g m)",
                  spec_.filter_type == FilterType::Cone ? "" : "the cone-equivalent 2 sqrt(3) r = ",
                  default_edge_);
    s += buf;
  }
  return s;
}

DesignField::~DesignField() {
  VecDestroy(&rho_);
  VecDestroy(&filtered_);
  VecDestroy(&physical_);
  VecDestroy(&work_);
}

DesignField::SurfaceContact
DesignField::touched_surface(const std::vector<std::string> &surfaces) const {
  const MPI_Comm comm = mesh_.comm;
  int size = 1;
  MPI_Comm_size(comm, &size);
  for (const std::string &name : surfaces) {
    // Every rank needs the whole surface: its design elements may touch nodes owned elsewhere.
    mesh_.surface(name, spec_.where.str() + ": interface");
    const std::vector<PetscInt> &own = mesh_.surface_nodes.at(name);
    const int n = static_cast<int>(own.size());
    std::vector<int> counts(static_cast<std::size_t>(size)),
        offsets(static_cast<std::size_t>(size));
    MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm);
    int total = 0;
    for (std::size_t r = 0; r < counts.size(); ++r) {
      offsets[r] = total;
      total += counts[r];
    }
    std::vector<PetscInt> all(static_cast<std::size_t>(total));
    MPI_Allgatherv(own.data(), n, MPIU_INT, all.data(), counts.data(), offsets.data(), MPIU_INT,
                   comm);
    std::sort(all.begin(), all.end());
    SurfaceContact local{name, 0, -1};
    const int npe = mesh_.nodes_per_element();
    for (std::size_t j = 0; j < design_elements_.size(); ++j) {
      const PetscInt e = design_elements_[j];
      for (int a = 0; a < npe; ++a) {
        const PetscInt node =
            mesh_.local_to_global(mesh_.connectivity[static_cast<std::size_t>(e * npe + a)]);
        if (std::binary_search(all.begin(), all.end(), node)) {
          if (local.elements++ == 0) local.tag = static_cast<long long>(design_tags_[j]);
          break;
        }
      }
    }
    SurfaceContact global{name, 0, -1};
    MPI_Allreduce(&local.elements, &global.elements, 1, MPI_LONG_LONG, MPI_SUM, comm);
    MPI_Allreduce(&local.tag, &global.tag, 1, MPI_LONG_LONG, MPI_MAX, comm);
    if (global.elements > 0) return global;
  }
  return {};
}

Vec DesignField::create_design_vector() const {
  Vec x;
  FX_PETSC(VecCreateMPI(mesh_.comm, static_cast<PetscInt>(design_elements_.size()), PETSC_DETERMINE,
                        &x));
  return x;
}

void DesignField::initial_design(Vec x) const {
  FX_PETSC(VecSet(x, spec_.initial));
}

void DesignField::update(Vec x) {
  FX_PETSC(VecSet(rho_, 1.0)); // elements outside the design region stay solid
  {
    const PetscScalar *xa;
    PetscScalar *r;
    FX_PETSC(VecGetArrayRead(x, &xa));
    FX_PETSC(VecGetArray(rho_, &r));
    for (std::size_t k = 0; k < design_elements_.size(); ++k) r[design_elements_[k]] = xa[k];
    FX_PETSC(VecRestoreArray(rho_, &r));
    FX_PETSC(VecRestoreArrayRead(x, &xa));
  }
  filter_->apply(rho_, filtered_);
  // Heaviside projection (Wang, Lazarov & Sigmund 2011), or the identity.
  const PetscInt n_el = mesh_.local_elements();
  dprojection_.assign(static_cast<std::size_t>(n_el), 1.0);
  FX_PETSC(VecCopy(filtered_, physical_));
  if (beta_ > 0) {
    const double eta = spec_.eta, den = std::tanh(beta_ * eta) + std::tanh(beta_ * (1.0 - eta));
    PetscScalar *ph;
    FX_PETSC(VecGetArray(physical_, &ph));
    for (PetscInt e = 0; e < n_el; ++e) {
      const double th = std::tanh(beta_ * (ph[e] - eta));
      dprojection_[static_cast<std::size_t>(e)] = beta_ * (1.0 - th * th) / den;
      ph[e] = (std::tanh(beta_ * eta) + th) / den;
    }
    FX_PETSC(VecRestoreArray(physical_, &ph));
  }
}

double DesignField::volume_fraction() const {
  const PetscScalar *rt;
  FX_PETSC(VecGetArrayRead(physical_, &rt));
  double local = 0;
  for (PetscInt e : design_elements_) local += rt[e] * volume_[static_cast<std::size_t>(e)];
  FX_PETSC(VecRestoreArrayRead(physical_, &rt));
  double total = 0;
  MPI_Allreduce(&local, &total, 1, MPI_DOUBLE, MPI_SUM, mesh_.comm);
  return total / design_volume_;
}

void DesignField::volume_fraction_gradient(Vec g) const {
  PetscScalar *ga;
  FX_PETSC(VecZeroEntries(g));
  FX_PETSC(VecGetArray(g, &ga));
  for (PetscInt e : design_elements_) ga[e] = volume_[static_cast<std::size_t>(e)] / design_volume_;
  FX_PETSC(VecRestoreArray(g, &ga));
}

namespace {

/// f(rho) and f'(rho) of every design element's physical density (1 and 0 elsewhere).
template <class F>
void interpolate(const DesignField &field, Vec physical, std::vector<double> &f,
                 std::vector<double> &df, PetscInt n, F &&law) {
  f.assign(static_cast<std::size_t>(n), 1.0);
  df.assign(static_cast<std::size_t>(n), 0.0);
  const PetscScalar *ph;
  FX_PETSC(VecGetArrayRead(physical, &ph));
  for (PetscInt e : field.design_elements()) {
    const auto k = static_cast<std::size_t>(e);
    law(std::max(ph[e], 0.0), f[k], df[k]);
  }
  FX_PETSC(VecRestoreArrayRead(physical, &ph));
}

} // namespace

void DesignField::stiffness_factors(std::vector<double> &s, std::vector<double> &ds) const {
  const double emin = spec_.min_stiffness, p = spec_.penalty;
  interpolate(*this, physical_, s, ds, mesh_.local_elements(),
              [&](double r, double &f, double &df) {
                f = emin + std::pow(r, p) * (1.0 - emin);
                df = r > 0 ? p * std::pow(r, p - 1.0) * (1.0 - emin) : 0.0;
              });
}

double DesignField::default_stress_exponent(double penalty) {
  return std::max(penalty - 1.5, 0.5 * penalty);
}

void DesignField::stress_factors(std::vector<double> &eta, std::vector<double> &deta) const {
  // qp-relaxation (docs/theory.md 5.1): eta = ((rho + d)^q - d^q) / ((1 + d)^q - d^q), the
  // shift d keeping eta' finite at rho = 0.
  const double q =
      spec_.stress_exponent > 0 ? spec_.stress_exponent : default_stress_exponent(spec_.penalty);
  const double d = kStressShift;
  const double d_q = std::pow(d, q), scale = 1.0 / (std::pow(1.0 + d, q) - d_q);
  interpolate(*this, physical_, eta, deta, mesh_.local_elements(),
              [&](double r, double &f, double &df) {
                const double rr = std::max(r, 0.0);
                f = (std::pow(rr + d, q) - d_q) * scale;
                df = q * std::pow(rr + d, q - 1.0) * scale;
              });
}

void DesignField::mass_factors(std::vector<double> &w, std::vector<double> &dw) const {
  const bool pedersen = spec_.mass == MassInterpolation::Pedersen;
  // pedersen keeps a floor of 1e-3 min_stiffness (docs/theory.md 9.1): 10^5 rho^6 underflows
  // for the voids of a projected design (rho ~ 1e-5 gives 1e-25), and an ACF body's nodes in
  // a massless, nearly stiffless void take unbounded accelerations from round-off forces at
  // the start (its elements invert in the first step). Measured: a floor of 1e-6 min_stiffness
  // suffices there; one of min_stiffness brings the void's local modes down among the lowest
  // six (LocalModes.*); 1e-3 sits between.
  const double floor = pedersen ? 1e-3 * spec_.min_stiffness : 0.0;
  interpolate(*this, physical_, w, dw, mesh_.local_elements(),
              [&](double r, double &f, double &df) {
                if (pedersen && r < 0.1) {
                  f = 1e5 * std::pow(r, 6);
                  df = 6e5 * std::pow(r, 5);
                } else {
                  f = r;
                  df = 1;
                }
                f = floor + (1 - floor) * f;
                df *= 1 - floor;
              });
}

void DesignField::pull_back(Vec g_physical, Vec g_x) const {
  PetscScalar *g;
  FX_PETSC(VecGetArray(g_physical, &g));
  for (PetscInt e = 0; e < mesh_.local_elements(); ++e)
    g[e] *= dprojection_[static_cast<std::size_t>(e)];
  FX_PETSC(VecRestoreArray(g_physical, &g));
  filter_->apply_transpose(g_physical, work_);
  const PetscScalar *f;
  PetscScalar *xa;
  FX_PETSC(VecGetArrayRead(work_, &f));
  FX_PETSC(VecGetArray(g_x, &xa));
  for (std::size_t k = 0; k < design_elements_.size(); ++k) xa[k] = f[design_elements_[k]];
  FX_PETSC(VecRestoreArray(g_x, &xa));
  FX_PETSC(VecRestoreArrayRead(work_, &f));
}

} // namespace flexopt::optimize
