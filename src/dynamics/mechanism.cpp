#include "flexopt/dynamics/mechanism.hpp"

#include "flexopt/core/error.hpp"

#include <cmath>

namespace flexopt::dynamics {

namespace {

/// An elastic part sized for a body with n elastic coordinates: zero if unset.
void size_elastic(joints::Elastic &S, int n, const std::string &owner) {
  if (S.cols() == n) return;
  if (S.cols() != 0)
    throw Error(owner + ": elastic part with " + std::to_string(S.cols()) +
                    " columns for a body with " + std::to_string(n) + " elastic coordinates",
                true);
  S = joints::Elastic::Zero(3, n);
}

} // namespace

void Mechanism::finalize() {
  offsets_.clear();
  coordinates_ = 0;
  for (const auto &b : bodies) {
    offsets_.push_back(coordinates_);
    coordinates_ += b->coordinates();
  }
  auto elastic = [&](int b) { return b < 0 ? 0 : size(b) - 7; };
  for (auto &e : equations) {
    e.oa = e.a < 0 ? 0 : offset(e.a);
    e.ob = e.b < 0 ? 0 : offset(e.b);
    e.na = elastic(e.a);
    e.nb = elastic(e.b);
    for (joints::Elastic *S : {&e.Sa, &e.Ua, &e.Ua2}) size_elastic(*S, e.na, e.owner);
    for (joints::Elastic *S : {&e.Sb, &e.Vb}) size_elastic(*S, e.nb, e.owner);
  }
  for (auto &f : forces) size_elastic(f.S, elastic(f.body), "force on body " + body(f.body).name());
  row_equation_.clear();
  row_index_.clear();
  for (std::size_t e = 0; e < equations.size(); ++e)
    for (int k = 0; k < equations[e].rows(); ++k) {
      row_equation_.push_back(static_cast<int>(e));
      row_index_.push_back(k);
    }
  all_rows_ = static_cast<int>(row_equation_.size());
  enforced_.assign(static_cast<std::size_t>(all_rows_), 1);
  active_rows_ = all_rows_;
  enforced_index_.resize(static_cast<std::size_t>(all_rows_));
  for (int r = 0; r < all_rows_; ++r) enforced_index_[static_cast<std::size_t>(r)] = r;
}

std::string Mechanism::describe_row(int r) const {
  const auto &e = equations[static_cast<std::size_t>(row_equation_[static_cast<std::size_t>(r)])];
  return e.owner + " equation " +
         std::to_string(e.row_in_owner + row_index_[static_cast<std::size_t>(r)] + 1);
}

std::vector<std::string> Mechanism::drop_redundant_rows(const Vector &q, double t, double tol) {
  const int n = coordinates();
  Matrix J = Matrix::Zero(all_rows_, n);
  int row = 0;
  for (const auto &e : equations) {
    e.gradient(q, t, J, row);
    row += e.rows();
  }
  std::vector<Vector> basis;
  std::vector<std::string> dropped;
  for (int r = 0; r < all_rows_; ++r) {
    Vector g = J.row(r).transpose();
    const double norm = g.norm();
    for (const Vector &b : basis) g -= b.dot(g) * b; // modified Gram-Schmidt
    for (const Vector &b : basis) g -= b.dot(g) * b; // and once more, for orthogonality
    if (g.norm() <= tol * std::max(norm, 1e-300)) {
      enforced_[static_cast<std::size_t>(r)] = 0;
      dropped.push_back(describe_row(r));
    } else {
      basis.push_back(g / g.norm());
    }
  }
  active_rows_ = static_cast<int>(basis.size());
  for (int r = 0, k = 0; r < all_rows_; ++r)
    enforced_index_[static_cast<std::size_t>(r)] =
        enforced_[static_cast<std::size_t>(r)] ? k++ : -1;
  return dropped;
}

const bodies::Mat3 *Mechanism::rotations(const Vector &q) const {
  rotations_.resize(bodies.size());
  for (std::size_t b = 0; b < bodies.size(); ++b)
    rotations_[b] = bodies::rotation(q.segment<4>(offsets_[b] + 3));
  return rotations_.data();
}

void Mechanism::all_constraint_values(const Vector &q, double t, Vector &phi) const {
  phi.resize(all_rows_);
  const bodies::Mat3 *A = rotations(q);
  int row = 0;
  for (const auto &e : equations) {
    e.evaluate(q, t, phi.data() + row, nullptr, 0, A);
    row += e.rows();
  }
}

void Mechanism::constraint(const Vector &q, double t, Vector &phi, Matrix *J) const {
  if (J) {
    J->setZero(active_rows_, coordinates());
    joints::DenseSink sink(J, nullptr);
    constraint(q, t, phi, sink);
    return;
  }
  Vector all;
  all_constraint_values(q, t, all);
  phi.resize(active_rows_);
  for (int r = 0, k = 0; r < all_rows_; ++r)
    if (enforced_[static_cast<std::size_t>(r)]) phi(k++) = all(r);
}

void Mechanism::add_constraint_hessian(const Vector &q, double t, const Vector &lambda,
                                       Matrix &H) const {
  joints::DenseSink sink(nullptr, &H);
  add_constraint_hessian(q, t, lambda, sink);
}

namespace {

/// Forwards gradient rows to another sink under their enforced-row number, dropping the rows
/// that are not enforced.
class EnforcedRows : public joints::Sink {
public:
  EnforcedRows(joints::Sink &inner, const std::vector<int> &map) : inner_(inner), map_(map) {}
  void add_row(int row, const joints::BodyRef &body, const joints::Row &g) override {
    const int k = map_[static_cast<std::size_t>(row)];
    if (k >= 0) inner_.add_row(k, body, g);
  }
  void add_block(const joints::BodyRef &bi, const joints::BodyRef &bj, int i0, int j0,
                 const Eigen::Ref<const Matrix> &B) override {
    inner_.add_block(bi, bj, i0, j0, B);
  }
  void add_product(const joints::BodyRef &bi, const joints::BodyRef &bj, double scale,
                   const joints::Jacobian &X, const joints::Jacobian &Y) override {
    inner_.add_product(bi, bj, scale, X, Y);
  }

private:
  joints::Sink &inner_;
  const std::vector<int> &map_;
};

} // namespace

void Mechanism::constraint(const Vector &q, double t, Vector &phi, joints::Sink &sink) const {
  phi.resize(active_rows_);
  EnforcedRows forward(sink, enforced_index_);
  const bodies::Mat3 *A = rotations(q);
  double values[3];
  int row = 0, k = 0;
  for (const auto &e : equations) {
    e.evaluate(q, t, values, &forward, row, A);
    for (int i = 0; i < e.rows(); ++i)
      if (enforced_[static_cast<std::size_t>(row + i)]) phi(k++) = values[i];
    row += e.rows();
  }
}

void Mechanism::add_constraint_hessian(const Vector &q, double t, const Vector &lambda,
                                       joints::Sink &sink) const {
  const bodies::Mat3 *A = rotations(q);
  int row = 0, k = 0;
  double l[3];
  for (const auto &e : equations) {
    bool any = false;
    for (int i = 0; i < e.rows(); ++i) {
      const bool on = enforced_[static_cast<std::size_t>(row + i)];
      l[i] = on ? lambda(k++) : 0.0;
      any = any || on;
    }
    if (any) e.add_hessian(q, t, l, sink, A);
    row += e.rows();
  }
}

void Mechanism::dynamics_blocks(const Vector &q, const Vector &v, const Vector &a, double t,
                                Vector &r, std::vector<Matrix> &K, std::vector<Matrix> &C,
                                std::vector<Matrix> &M) const {
  const std::size_t nb = bodies.size();
  K.resize(nb);
  C.resize(nb);
  M.resize(nb);
  evaluate_dynamics(q, v, a, t, r, &K, &C, &M);
}

void Mechanism::evaluate_dynamics(const Vector &q, const Vector &v, const Vector &a, double t,
                                  Vector &r, std::vector<Matrix> *K, std::vector<Matrix> *C,
                                  std::vector<Matrix> *M) const {
  r.setZero(coordinates());
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    const int o = offsets_[b], m = bodies[b]->coordinates();
    bodies[b]->residual(q.segment(o, m), v.segment(o, m), a.segment(o, m), gravity, r.segment(o, m),
                        K ? &(*K)[b] : nullptr, C ? &(*C)[b] : nullptr, M ? &(*M)[b] : nullptr);
  }
  bodies::Mat4 pp;
  Eigen::Matrix<double, 4, Eigen::Dynamic> pz;
  for (const PointForce &pf : forces) {
    const int o = offset(pf.body), m = size(pf.body);
    const Vec3 F(pf.value[0](t), pf.value[1](t), pf.value[2](t));
    const auto qb = q.segment(o, m);
    r.segment(o, m) -= joints::anchor_jacobian(qb, pf.s, pf.S).transpose() * F;
    if (!K) continue;
    joints::anchor_hessian(qb, pf.s, pf.S, F, pp, pz);
    Matrix &Kb = (*K)[static_cast<std::size_t>(pf.body)];
    Kb.block<4, 4>(3, 3) -= pp;
    if (pz.cols() > 0) {
      Kb.block(3, 7, 4, pz.cols()) -= pz;
      Kb.block(7, 3, pz.cols(), 4) -= pz.transpose();
    }
  }
}

void Mechanism::dynamics_residual(const Vector &q, const Vector &v, const Vector &a, double t,
                                  Vector &r) const {
  evaluate_dynamics(q, v, a, t, r, nullptr, nullptr, nullptr);
}

void Mechanism::constraint_time_terms(const Vector &q, const Vector &v, double t, Vector &phi_t,
                                      Vector &phi_tt, Vector &phi_qt_v) const {
  phi_t.resize(active_rows_);
  phi_tt.resize(active_rows_);
  phi_qt_v.resize(active_rows_);
  int row = 0, k = 0;
  double a[3], b[3], c[3];
  for (const auto &e : equations) {
    e.time_derivatives(q, v, t, a, b, c);
    for (int i = 0; i < e.rows(); ++i)
      if (enforced_[static_cast<std::size_t>(row + i)]) {
        phi_t(k) = a[i], phi_tt(k) = b[i], phi_qt_v(k) = c[i];
        ++k;
      }
    row += e.rows();
  }
}

Vector Mechanism::constraint_convective(const Vector &q, const Vector &v, double t) const {
  const int n = coordinates();
  Vector out(active_rows_);
  Matrix H(n, n);
  int row = 0, k = 0;
  for (const auto &e : equations) {
    for (int i = 0; i < e.rows(); ++i) {
      if (!enforced_[static_cast<std::size_t>(row + i)]) continue;
      double l[3] = {0, 0, 0};
      l[i] = 1;
      H.setZero();
      e.add_hessian(q, t, l, H);
      out(k++) = v.dot(H * v);
    }
    row += e.rows();
  }
  return out;
}

void Mechanism::dynamics(const Vector &q, const Vector &v, const Vector &a, double t, Vector &r,
                         Matrix *K, Matrix *C, Matrix *M) const {
  std::vector<Matrix> Kb, Cb, Mb;
  dynamics_blocks(q, v, a, t, r, Kb, Cb, Mb);
  const int n = coordinates();
  // The equations of motion couple bodies only through the constraints: block diagonal.
  for (auto [out, blocks] : {std::pair{K, &Kb}, std::pair{C, &Cb}, std::pair{M, &Mb}}) {
    if (!out) continue;
    out->setZero(n, n);
    for (std::size_t b = 0; b < bodies.size(); ++b)
      out->block(offsets_[b], offsets_[b], (*blocks)[b].rows(), (*blocks)[b].cols()) = (*blocks)[b];
  }
}

double Mechanism::energy(const Vector &q, const Vector &v) const {
  double e = 0;
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    const int o = offsets_[b], m = bodies[b]->coordinates();
    e += bodies[b]->energy(q.segment(o, m), v.segment(o, m), gravity);
  }
  return e;
}

} // namespace flexopt::dynamics
