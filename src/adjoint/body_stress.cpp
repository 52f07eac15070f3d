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
  return optimize::describe_stress_response(name, r_, aggregate_, scale_);
}

AcfStress::AcfStress(const optimize::ResponseSettings &r, const bodies::AcfBody &body)
    : BodyStress(r, body.mesh(), body.material()), body_(body) {
  const Eigen::Vector3d xi = fem::reference_centroid(mesh_.type);
  S_.reserve(elements_.size());
  for (PetscInt e : elements_)
    S_.push_back(
        fem::element_stress_matrix(mesh_.type, mesh_.element_coordinates(e), material_, xi));
}

void AcfStress::start(std::size_t steps, double h, const std::vector<double> &eta,
                      const std::vector<double> &deta) {
  aggregate_.clear();
  steps_ = steps;
  recorded_ = 0;
  h_ = h;
  eta_ = eta;
  deta_ = deta;
}

void AcfStress::record(const double *u) {
  const std::vector<fem::CorotatedElement> &ce = body_.elements();
  const double w = trapezoid_weight(recorded_, steps_), t = static_cast<double>(recorded_) * h_;
  for (std::size_t i = 0; i < elements_.size(); ++i) {
    const PetscInt e = elements_[i];
    const double v = fem::corotated_von_mises(ce[static_cast<std::size_t>(e)], S_[i],
                                              body_.positions(e, u), nullptr);
    aggregate_.add(eta_of(eta_, i) * v, w, tag_of(i), t);
  }
  ++recorded_;
}

double AcfStress::finish(double h, const std::vector<double> &eta, const std::vector<double> &deta,
                         bool gradients) {
  (void)h, (void)eta, (void)deta, (void)gradients; // start()'s; the explicit part comes later
  aggregate_.reduce(mesh_.comm);
  return scale_ * aggregate_.value();
}

void AcfStress::add_state_partial(std::size_t n, const double *u, double *force,
                                  double *explicit_gradient) const {
  // The samples of step n again (the state is the forward run's), each with its weight in R
  // (section 8.3): g = c dR/dsigma^, force += g eta dv/dx, explicit += g eta' v.
  const std::vector<fem::CorotatedElement> &ce = body_.elements();
  const int npe = mesh_.nodes_per_element();
  const double w = trapezoid_weight(n, steps_);
  fem::ElementVector grad;
  for (std::size_t i = 0; i < elements_.size(); ++i) {
    const PetscInt e = elements_[i];
    const auto k = static_cast<std::size_t>(e);
    const double v = fem::corotated_von_mises(ce[k], S_[i], body_.positions(e, u), &grad);
    const double et = eta_of(eta_, i), g = scale_ * aggregate_.derivative(et * v, w);
    if (g == 0.0) continue;
    if (explicit_gradient && !deta_.empty()) explicit_gradient[k] += g * deta_[k] * v;
    for (int a = 0; a < npe; ++a) {
      const PetscInt node = mesh_.connectivity[static_cast<std::size_t>(e * npe + a)];
      for (int c = 0; c < 3; ++c) force[3 * node + c] += g * et * grad(3 * a + c);
    }
  }
}

} // namespace flexopt::adjoint
