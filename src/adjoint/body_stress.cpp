// Stress responses on flexible bodies in a dynamic analysis: what every body model shares, and
// the ACF body's co-rotated stress (docs/theory.md sections 8.3 and 10.3).
#include "flexopt/adjoint/body_stress.hpp"

#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/bodies/acf_body.hpp"
#include "flexopt/fem/corotated.hpp"
#include "flexopt/optimize/static_stress.hpp"

namespace flexopt::adjoint {

BodyStress::BodyStress(const optimize::ResponseSettings &r, const mesh::DistributedMesh &mesh,
                       const fem::IsotropicMaterial &material)
    : r_(r), mesh_(mesh), material_(material), elements_(optimize::stress_elements(mesh, r)),
      aggregate_(r.aggregate) {}

void BodyStress::end_iteration() {
  if (r_.adaptive) scale_ = optimize::next_scale(scale_, aggregate_);
}

io::Json BodyStress::describe(const std::string &name) const {
  io::Json j = io::Json::object();
  j["response"] = name;
  j["body"] = r_.body;
  j["aggregate"] = r_.aggregate.type == optimize::StressAggregateType::Ks ? "ks" : "pnorm";
  j["value"] = scale_ * aggregate_.value();
  j["unscaled_value"] = aggregate_.value();
  j["scale"] = scale_;
  j["peak"] = aggregate_.peak();
  j["peak_element"] = aggregate_.peak_tag();
  j["peak_time"] = aggregate_.peak_time();
  if (r_.has_max) {
    j["max"] = r_.max;
    j["peak_over_max"] = aggregate_.peak() / r_.max;
  }
  return j;
}

AcfStress::AcfStress(const optimize::ResponseSettings &r, const bodies::AcfBody &body)
    : BodyStress(r, body.mesh(), body.material()), body_(body) {
  const Eigen::Vector3d xi = fem::reference_centroid(mesh_.type);
  S_.reserve(elements_.size());
  for (PetscInt e : elements_)
    S_.push_back(
        fem::element_stress_matrix(mesh_.type, mesh_.element_coordinates(e), material_, xi));
}

void AcfStress::record(const double *u) {
  const std::vector<fem::CorotatedElement> &ce = body_.elements();
  for (std::size_t i = 0; i < elements_.size(); ++i) {
    const PetscInt e = elements_[i];
    const fem::CorotatedElement &el = ce[static_cast<std::size_t>(e)];
    v_.push_back(fem::corotated_von_mises(el, S_[i], body_.positions(e, u), nullptr));
  }
}

double AcfStress::finish(double h, const std::vector<double> &eta, const std::vector<double> &deta,
                         bool gradients) {
  aggregate_.clear();
  const std::size_t ne = elements_.size(), steps = ne == 0 ? 0 : v_.size() / ne;
  // The step count is the same on every rank (a rank without elements of the region samples
  // nothing): the weights need the last step's index.
  unsigned long long local = steps, all = 0;
  MPI_Allreduce(&local, &all, 1, MPI_UNSIGNED_LONG_LONG, MPI_MAX, mesh_.comm);
  const std::size_t N = all == 0 ? 0 : static_cast<std::size_t>(all) - 1;
  for (std::size_t n = 0; n < steps; ++n)
    for (std::size_t i = 0; i < ne; ++i)
      aggregate_.add(eta_of(eta, i) * v_[n * ne + i], trapezoid_weight(n, N), tag_of(i),
                     static_cast<double>(n) * h);
  aggregate_.reduce(mesh_.comm);
  if (!gradients) return scale_ * aggregate_.value();
  g_.assign(v_.size(), 0.0);
  explicit_.assign(static_cast<std::size_t>(mesh_.local_elements()), 0.0);
  for (std::size_t n = 0; n < steps; ++n)
    for (std::size_t i = 0; i < ne; ++i) {
      const double v = v_[n * ne + i], et = eta_of(eta, i);
      const double g = scale_ * aggregate_.derivative(et * v, trapezoid_weight(n, N));
      g_[n * ne + i] = g * et;
      if (!deta.empty())
        explicit_[static_cast<std::size_t>(elements_[i])] += g * deta[elements_[i]] * v;
    }
  return scale_ * aggregate_.value();
}

void AcfStress::add_state_partial(std::size_t n, const double *u, double *force) const {
  const std::vector<fem::CorotatedElement> &ce = body_.elements();
  const std::size_t ne = elements_.size();
  const int npe = mesh_.nodes_per_element();
  fem::ElementVector grad;
  for (std::size_t i = 0; i < ne; ++i) {
    const double g = g_[n * ne + i];
    if (g == 0.0) continue;
    const PetscInt e = elements_[i];
    const fem::CorotatedElement &el = ce[static_cast<std::size_t>(e)];
    fem::corotated_von_mises(el, S_[i], body_.positions(e, u), &grad);
    for (int a = 0; a < npe; ++a) {
      const PetscInt node = mesh_.connectivity[static_cast<std::size_t>(e * npe + a)];
      for (int c = 0; c < 3; ++c) force[3 * node + c] += g * grad(3 * a + c);
    }
  }
}

} // namespace flexopt::adjoint
