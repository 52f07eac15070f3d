#pragma once
/// \file Kineto-elastodynamics (KED): the linear elastic response of a body's reduced model to
/// the forcing of its rigid motion, one-way coupled (docs/theory.md section 12.1). Small dense
/// algebra (Eigen), the same on every rank.
#include <Eigen/Dense>
#include <vector>

namespace flexopt::plan {

/// How the modal responses start: at rest (x = x' = 0), or in the quasi-static state of the
/// first forcing sample, x(0) = f(0) / w^2, x'(0) = (f(h) - f(0)) / (h w^2).
enum class Start { Rest, QuasiStatic };

/// The responses x_k of x_k'' + w2_k x_k = f_k(t) from `start`, for forcing f linear between
/// the samples t_n = n h (row n of F is f(t_n)); exact (Duhamel's integral of each mode).
/// Returns the (rows of F) x (modes) displacements. w2_k > 0.
Eigen::MatrixXd modal_response(const Eigen::VectorXd &w2, const Eigen::MatrixXd &F, double h,
                               Start start = Start::Rest);

/// A reduced model of a body: the M-orthonormal modes E (coordinates in the full basis, one
/// column per mode) and their squared frequencies w2 (ascending).
struct ModalModel {
  Eigen::MatrixXd E;
  Eigen::VectorXd w2;
};

/// The model spanned by the first `columns` columns of B (coordinates in a basis where the
/// stiffness is K and the mass M): the eigenpairs of (B^T K B, B^T M B), the modes mapped back
/// to the full basis. With B = I it is the full model. Throws flexopt::Error if the projected
/// mass is singular.
ModalModel modal_model(const Eigen::MatrixXd &K, const Eigen::MatrixXd &M, const Eigen::MatrixXd &B,
                       int columns);

/// The KED response of `model` to the forcing Q (rows: samples at t_n = n h; columns: the full
/// basis' generalized forces), started quasi-statically (docs/theory.md section 12.1): the
/// full-basis coordinates zeta(t_n) = E x(t_n), one row per sample.
Eigen::MatrixXd ked_response(const ModalModel &model, const Eigen::MatrixXd &Q, double h);

/// e_qs of docs/theory.md section 14.5 (when equivalent static loads suffice): the largest
/// distance over the samples of the KED response Z (ked_response of `model` to Q; rows:
/// samples, full-basis coordinates; M the full basis' mass matrix) from its quasi-static part,
/// modal coordinates x_qs = (E^T Q) / w2, in the energy norm |x|^2 = sum_k w2_k x_k^2, relative to
/// the response's largest energy norm (0 for a response that is zero).
double quasi_static_error(const ModalModel &model, const Eigen::MatrixXd &M,
                          const Eigen::MatrixXd &Z, const Eigen::MatrixXd &Q);
/// The response zeta of zeta'' + K(t) zeta = Q(t) (unit mass) with the stiffness
/// K(t) = K + sum_r c_r(t) G[r] (row n of `coefficients`: c(t_n)), from rest or quasi-statically
/// in K(0) (K(0) zeta(0) = Q(0), K(0) zeta'(0) = (Q(h) - Q(0)) / h); each step is integrated
/// exactly in the eigenbasis of the stiffness frozen at the step's midpoint (the mean of its
/// two samples), second order in h (docs/theory.md section 12.2). Rows: the samples of Q.
/// `lowest` (if given) receives the smallest eigenvalue of the stiffness met; where it is not
/// positive the integration stops and the remaining rows are zero.
Eigen::MatrixXd ked_response_varying(const Eigen::MatrixXd &K,
                                     const std::vector<Eigen::MatrixXd> &G,
                                     const Eigen::MatrixXd &coefficients, const Eigen::MatrixXd &Q,
                                     double h, Start start = Start::QuasiStatic,
                                     double *lowest = nullptr);

} // namespace flexopt::plan
