// The design of several design bodies as one vector (docs/theory.md 9.9).
#include "flexopt/optimize/design.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/mesh/grid_layout.hpp"

#include <algorithm>

namespace flexopt::optimize {

Design::Design(std::vector<std::unique_ptr<DesignField>> fields) : fields_(std::move(fields)) {
  if (fields_.empty()) throw Error("Design: no design field", true);
  PetscInt at = 0;
  for (std::size_t k = 0; k < fields_.size(); ++k) {
    const DesignField &f = *fields_[k];
    local_.push_back(static_cast<PetscInt>(f.design_tags().size()));
    offset_.push_back(at);
    at += local_.back();
    global_ += f.design_size();
    for (std::size_t tag : f.design_tags())
      keys_.push_back(key(k, tag)); // Gmsh tags stay far below 2^48
    Vec part;
    FX_PETSC(VecCreateMPIWithArray(comm(), 1, local_.back(), PETSC_DETERMINE, nullptr, &part));
    parts_.push_back(part);
  }
  local_total_ = at;
}

Design::~Design() {
  for (Vec &v : parts_) VecDestroy(&v);
}

Vec Design::create_design_vector() const {
  Vec x;
  FX_PETSC(VecCreateMPI(comm(), local_total_, global_, &x));
  return x;
}

void Design::initial_design(Vec x) const {
  PetscScalar *a;
  FX_PETSC(VecGetArray(x, &a));
  for (std::size_t k = 0; k < fields_.size(); ++k)
    std::fill(a + offset_[k], a + offset_[k] + local_[k], fields_[k]->settings().initial);
  FX_PETSC(VecRestoreArray(x, &a));
}

void Design::update(Vec x) {
  const PetscScalar *a;
  FX_PETSC(VecGetArrayRead(x, &a));
  for (std::size_t k = 0; k < fields_.size(); ++k) {
    FX_PETSC(VecPlaceArray(parts_[k], a + offset_[k]));
    fields_[k]->update(parts_[k]);
    FX_PETSC(VecResetArray(parts_[k]));
  }
  FX_PETSC(VecRestoreArrayRead(x, &a));
}

void Design::pull_back(std::size_t k, Vec g_physical, Vec g_x) {
  PetscScalar *a;
  FX_PETSC(VecGetArray(g_x, &a));
  FX_PETSC(VecPlaceArray(parts_[k], a + offset_[k]));
  fields_[k]->pull_back(g_physical, parts_[k]);
  FX_PETSC(VecResetArray(parts_[k]));
  FX_PETSC(VecRestoreArray(g_x, &a));
}

int Design::stages() const {
  std::size_t n = 0;
  for (const auto &f : fields_) n = std::max(n, f->settings().beta.size());
  return static_cast<int>(n);
}

void Design::set_stage(int stage) {
  for (const auto &f : fields_) {
    const std::vector<double> &beta = f->settings().beta;
    if (!beta.empty())
      f->set_beta(beta[std::min(static_cast<std::size_t>(stage), beta.size() - 1)]);
  }
}

int Design::stage_length() const {
  for (const auto &f : fields_)
    if (!f->settings().beta.empty()) return f->settings().beta_every;
  return fields_.front()->settings().beta_every;
}

std::string Design::stage_text(int stage) const {
  std::string s;
  char buf[64];
  for (const auto &f : fields_) {
    const std::vector<double> &beta = f->settings().beta;
    if (beta.empty()) continue;
    std::snprintf(buf, sizeof buf, "%g",
                  beta[std::min(static_cast<std::size_t>(stage), beta.size() - 1)]);
    if (!s.empty()) s += ", ";
    s += fields_.size() > 1 ? f->settings().body + " " + buf : std::string(buf);
  }
  return s;
}

std::vector<double> Design::betas() const {
  std::vector<double> b;
  for (const auto &f : fields_) b.push_back(f->beta());
  return b;
}

void Design::set_betas(const std::vector<double> &betas) {
  for (std::size_t k = 0; k < fields_.size() && k < betas.size(); ++k)
    fields_[k]->set_beta(betas[k]);
}

namespace {
/// Whether `bodies` (empty: every body) lists field f's body.
bool listed(const std::vector<std::string> &bodies, const DesignField &f) {
  return bodies.empty() ||
         std::find(bodies.begin(), bodies.end(), f.settings().body) != bodies.end();
}
} // namespace

double Design::volume_fraction(const std::vector<std::string> &bodies) const {
  if (fields_.size() == 1) return fields_.front()->volume_fraction();
  double solid = 0, volume = 0;
  for (const auto &f : fields_)
    if (listed(bodies, *f)) {
      solid += f->volume_fraction() * f->design_volume();
      volume += f->design_volume();
    }
  return solid / volume;
}

void Design::volume_fraction_gradient(const std::vector<std::string> &bodies, std::size_t k,
                                      Vec g) const {
  fields_[k]->volume_fraction_gradient(g);
  if (fields_.size() == 1) return;
  double volume = 0;
  for (const auto &f : fields_)
    if (listed(bodies, *f)) volume += f->design_volume();
  FX_PETSC(VecScale(g, listed(bodies, *fields_[k]) ? fields_[k]->design_volume() / volume : 0.0));
}

std::string Design::filter_description() const {
  if (fields_.size() == 1) return fields_.front()->filter_description();
  std::string s;
  for (const auto &f : fields_)
    s += (s.empty() ? "" : "; ") + f->settings().body + ": " + f->filter_description();
  return s;
}

io::GridLayout Design::grid_layout(const std::vector<std::vector<double>> &placed) const {
  std::vector<const mesh::DistributedMesh *> meshes;
  for (const auto &f : fields_) meshes.push_back(&f->mesh());
  return mesh::merged_grid_layout(meshes, placed);
}

std::vector<double> Design::cells(Vec (DesignField::*which)() const) const {
  std::vector<double> out;
  for (const auto &f : fields_) {
    Vec v = ((*f).*which)();
    const PetscScalar *a;
    PetscInt n = 0;
    FX_PETSC(VecGetLocalSize(v, &n));
    FX_PETSC(VecGetArrayRead(v, &a));
    out.insert(out.end(), a, a + n);
    FX_PETSC(VecRestoreArrayRead(v, &a));
  }
  return out;
}

long long Design::global_elements() const {
  long long n = 0;
  for (const auto &f : fields_) n += f->mesh().global_elements;
  return n;
}

std::vector<std::vector<double>>
Design::placed_coordinates(const std::vector<std::array<double, 12>> &placements) const {
  std::vector<std::vector<double>> placed;
  for (std::size_t k = 0; k < fields_.size(); ++k) {
    const std::array<double, 12> &pl = placements.at(k);
    const mesh::DistributedMesh &m = fields_[k]->mesh();
    std::vector<double> x(static_cast<std::size_t>(3 * m.owned_nodes));
    for (std::size_t i = 0; i < x.size() / 3; ++i)
      for (std::size_t r = 0; r < 3; ++r) {
        double v = pl[r];
        for (std::size_t c = 0; c < 3; ++c) v += pl[3 + 3 * r + c] * m.coordinates[3 * i + c];
        x[3 * i + r] = v;
      }
    placed.push_back(std::move(x));
  }
  return placed;
}

} // namespace flexopt::optimize
