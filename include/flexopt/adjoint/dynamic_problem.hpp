#pragma once
/// \file Topology optimization responses of a dynamic analysis and their discrete-adjoint
/// gradients (docs/theory.md section 9): the scene is built once (meshes, joints, sensors);
/// each evaluation sets the design body's mass parameters from the densities, runs the
/// forward generalized-alpha integration storing its states, evaluates the responses on the
/// time grid, and runs the backward sweep with the design partials and the adjoint of the
/// consistent initial state.
#include "flexopt/adjoint/checkpoints.hpp"
#include "flexopt/adjoint/ffrf_stress.hpp"
#include "flexopt/adjoint/step_adjoint.hpp"
#include "flexopt/bodies/ffrf_body.hpp"
#include "flexopt/bodies/rigid_body.hpp"
#include "flexopt/dynamics/integrator.hpp"
#include "flexopt/dynamics/scene.hpp"
#include "flexopt/dynamics/scene_description.hpp"
#include "flexopt/optimize/design.hpp"
#include "flexopt/optimize/design_problem.hpp"
#include "flexopt/optimize/response.hpp"
#include "flexopt/reduce/reduction_adjoint.hpp"

#include <functional>
#include <memory>
#include <mpi.h>
#include <string>
#include <vector>

namespace flexopt::adjoint {

namespace detail {
template <class State, class Trace> class PassRun;
class DensePass;
class DistPass;
} // namespace detail

/// d r / d theta contracted with weights: G = (d r/d theta)^T W at the mechanism state (q, v, a)
/// (r the dynamics residual of Mechanism::dynamics, with or without gravity; theta the design
/// parameters; W has one column per response). The adjoint of the initial state calls it for
/// the accelerations (with gravity) and for the mass matrix of the velocity correction (v = 0,
/// no gravity: r = M a).
using bodies::Vec3;

using ResidualPartials = std::function<Matrix(const Vector &q, const Vector &v, const Vector &a,
                                              bool gravity, const Matrix &W)>;

/// What the adjoint of the consistent initial state returns (one column per response).
struct StartAdjoint {
  Matrix design; ///< dPsi/dtheta through the start
  /// With `given`: dPsi/dq_g and dPsi/dv_g, the sensitivities to the placed coordinates and
  /// velocities, and per response the cotangent of the positions' metric (n x n, section 9.2
  /// item 6: only its block on a design body's elastic coordinates means anything).
  Matrix q, v;
  std::vector<Matrix> metric;
};

/// The adjoint of the consistent initial state (docs/theory.md section 9.2): from
/// gbar = dPsi/ds_0 (packed like State::pack, one column per response; = -mu_0 of the sweep),
/// the state s0 that GeneralizedAlpha::initial_state computed and its `trace` (what the start
/// did), returns dPsi/dtheta through the accelerations, multipliers and the velocity
/// corrections (the rigid-body one and the elastic fallback) and, if `given`, the
/// sensitivities to the placed coordinates and velocities through every stage (item 6).
StartAdjoint initial_state_adjoint(const dynamics::GeneralizedAlpha &ga, const dynamics::State &s0,
                                   const dynamics::StartTrace &trace, const Matrix &gbar,
                                   const ResidualPartials &partials, bool given = false);

/// A response of a dynamic analysis on the time grid (docs/theory.md section 9.3): the sensor
/// samples y_n at the main steps give Psi and dPsi/dy_n.
struct SampledResponse {
  double value = 0;
  std::vector<Vec3> dy; ///< dPsi/dy_n per main step (empty: no trajectory dependence)
};
/// Psi and dPsi/dy_n of a tracking_error or sensor response from the samples y (one per main
/// step n = 0 ... N at t_n = n h). Throws a collective flexopt::Error naming the response if a
/// target is not finite.
SampledResponse sampled_response(const optimize::ResponseSettings &r, const std::vector<Vec3> &y,
                                 double h);

/// dy/dq of a sensor of a rigid or FFRF body of the scene's mechanism at q (3 x n, the body's
/// columns only; position and displacement: the anchor Jacobian, elastic displacement: S).
Matrix sensor_jacobian(const dynamics::Scene &scene, const dynamics::BoundSensor &s,
                       const Vector &q);

/// The trapezoidal weight of main step n of N in a time average (section 9.3): 1/(2N) at the
/// ends, 1/N between (1 for N = 0).
double trapezoid_weight(std::size_t n, std::size_t N);

/// Where the backward sweep's checkpoints are kept (`adjoint.storage`).
enum class CheckpointStorage { Memory, Disk };

/// `adjoint:` of a dynamic optimization (section 9.4).
struct CheckpointSettings {
  int checkpoints = 0; ///< stored states; 0: all (`checkpoints: all`)
  CheckpointStorage storage = CheckpointStorage::Memory; ///< disk: an HDF5 file per rank
  /// FFRF design bodies: the exact derivative of the basis, or the basis held fixed
  reduce::BasisDerivative basis = reduce::BasisDerivative::Exact;
  /// In the checkpoint files' names (a scenario's: adjoint_checkpoints.TAG.RANK.h5), so that
  /// scenarios on groups of ranks do not share one.
  std::string file_tag;
  io::Location where;
};

/// What a dynamic design problem reads: the scene and its time grid, the design field of each
/// design body, the responses and the checkpointing of the backward sweep.
struct DynamicSettings {
  dynamics::SceneDescription scene;
  dynamics::TimeSettings time;
  std::vector<optimize::DesignSettings> design;
  optimize::ResponseSettings objective;
  std::vector<optimize::ResponseSettings> constraints;
  CheckpointSettings adjoint;
};

/// One design body of a dynamic design problem (docs/theory.md 9.9): its design field, where it
/// sits in the scene, its model's design data, and what the last evaluation computed for it.
struct DesignBody {
  optimize::DesignField *field = nullptr; ///< the Design's field `index`
  std::size_t index = 0;
  int body = -1;      ///< case (and scene) body index
  int mechanism = -1; ///< index in the mechanism (rigid, FFRF: also the distributed small part)
  int acf = -1;       ///< index among the scene's ACF bodies (ACF)
  dynamics::BodyModel model = dynamics::BodyModel::Rigid;
  int row = 0;  ///< first row of its block in the stacked design partials (rigid, FFRF)
  int rows = 0; ///< that block's rows: 10 mass parameters (rigid) or the packed FfrfModel
  Vec grad_physical = nullptr; ///< work: a gradient on its physical densities
  /// Rigid: the reference point (section 9.1) and each local element's mass parameters.
  bodies::Vec3 reference{0, 0, 0};
  std::vector<bodies::MassParameters> element_theta;
  /// FFRF: the reduction at the last design (with its adjoint data) and the element factors it
  /// was made with (a new design with the same factors, the first one in particular, reuses it).
  std::shared_ptr<const reduce::FlexibleReduction> reduction;
  reduce::ElementFactors reduced_factors;
  double reduction_s = 0, reduction_adjoint_s = 0; ///< of the last reduction and its adjoint
  int reduction_cg_iterations = 0;
  bool rigid() const { return model == dynamics::BodyModel::Rigid; }
  bool ffrf() const { return model == dynamics::BodyModel::Ffrf; }
  bool acf_model() const { return model == dynamics::BodyModel::Acf; }
  /// What one evaluation computes for the body (evaluate starts it anew).
  struct Evaluated {
    /// Mass factors w and SIMP modulus factors s per local element and their derivatives; the
    /// rigid body's mass parameters.
    std::vector<double> w, dw, s, ds;
    bodies::MassParameters theta = bodies::MassParameters::Zero();
    /// Per response on an FFRF body's strain energy: sum_n w_n 1/2 zeta_n zeta_n^T.
    std::vector<Matrix> strain_kbar;
    /// Per response: dPsi/d(physical density) of every local element.
    std::vector<std::vector<double>> element_gradient;
    double reduction_s = 0, reduction_adjoint_s = 0;
  } ev;
};

class DynamicProblem : public optimize::DesignProblem {
public:
  /// Builds the scene (meshes, joints, sensors) and the design field of `settings`. `scratch` is
  /// the directory of the checkpoint file of `adjoint: {storage: disk}` (the command's output
  /// directory). Collective; throws collective flexopt::Errors with case.yaml:line:col for a design
  /// body whose model has no design partials yet, responses on missing or unsuitable bodies and
  /// sensors. `refuse_interfaces` (optimize): a design region that touches an interface of its FFRF
  /// or ACF body is an error, else a warning (checked before the reduction).
  static std::unique_ptr<DynamicProblem> create(MPI_Comm comm, const DynamicSettings &settings,
                                                const std::string &scratch,
                                                bool refuse_interfaces = false);
  ~DynamicProblem() override;

  optimize::Design &design() override { return *design_; }
  const optimize::Design &design() const override { return *design_; }
  /// Several design bodies: each in its initial placement (x = position + R X, the scene's), so
  /// that they appear where they sit in the mechanism; one keeps its mesh coordinates.
  io::GridLayout design_layout() const override;
  std::vector<std::array<double, 12>> design_placements() const override;
  const std::vector<std::string> &response_names() const override { return names_; }
  void evaluate(Vec x, bool gradients, optimize::Evaluation &out) override;
  /// A caller's view of the forward runs of evaluate (not of the recomputations from
  /// checkpoints): after main step j the state on the dense backend (`dense`) or the
  /// distributed one (`dist`; the other pointer is null) with the step's Newton figures; j = 0:
  /// the consistent start (info empty). `simulate` writes its output from it, so that a design
  /// is integrated once. Called on every rank.
  using StepObserver =
      std::function<void(long long j, const dynamics::StepInfo &info, const dynamics::State *dense,
                         const dynamics::DistState *dist)>;
  void set_observer(StepObserver observer) { observer_ = std::move(observer); }
  /// Puts the design x into the scene as evaluate does (the ACF design bodies' element factors,
  /// the rigid ones' mass parameters, the FFRF ones' reductions), without integrating.
  /// Collective.
  void apply_design(Vec x);
  /// dofs, elements, design_variables, steps, forward_s, adjoint_s, checkpoints,
  /// recomputed_steps, checkpoint_bytes, evaluations.
  void describe(io::Json &summary) const override;
  /// 1e-12 L for a sensor response's final value or KS maximum, (1e-12 L)^2 for its mean square
  /// and a tracking error (L the scene's length scale); 0 for the others.
  double round_off_level(std::size_t i) const override;
  /// 1e-12: every step is solved to Newton's tolerance 1e-12 (relative increment), whose error
  /// reaches the responses (measured remainders of the Taylor test clean to 1e-14 relative).
  /// 1e-8 with an FFRF design body: the lowest eigenpairs of the body's assembled K, M are
  /// determined only to about eps lambda_max / lambda_1 (docs/theory.md section 10,
  /// "Accuracy": 1.3e-9 relative on tests/gradient/ffrf_pendulum, as -eps_ncv changes them).
  double noise_floor() const override { return ffrf_design_ ? 1e-8 : 1e-12; }
  /// The design bodies, in the order of `design:`.
  const std::vector<DesignBody> &design_bodies() const { return designs_; }
  /// 1e-14 for the volume fraction and a mass (sums over the densities: no state, no
  /// reduction), else noise_floor().
  double noise_floor(std::size_t i) const override;
  /// 1e-2; with an FFRF design body 0.2 and 6 halvings: its responses carry the noise of the
  /// reduction (noise_floor()), so one element's difference quotient errs by noise / h at small
  /// steps and by the truncation at large ones, and where they balance depends on the scene
  /// (tests/gradient/ffrf_pendulum: best near 0.2; ffrf_slider_crank: near 1e-2).
  double fd_step() const override { return ffrf_design_ ? 0.2 : 1e-2; }
  int fd_levels() const override { return ffrf_design_ ? 6 : 1; }
  /// The mechanism's coordinates and the ACF bodies' node coordinates.
  long long dofs() const override;
  /// The stress responses of the last evaluation: per response its key ("objective",
  /// "constraint0", ...), body, true peak [Pa], its element's Gmsh tag and time [s].
  struct StressSummary {
    std::string key, body;
    double peak = 0;
    long long element = -1;
    double time = 0;
  };
  std::vector<StressSummary> stress_summaries() const;
  /// The same as summary.json's "stress" (BodyStress::describe per stress response), or null.
  io::Json stress_json() const;
  /// The stress responses' adaptive normalization (docs/theory.md 5.1).
  void end_iteration() override;
  std::vector<double> response_scales() const override;
  std::vector<DesignStress> design_stress() const override;
  void restore_response_scales(const std::vector<double> &scales) override;
  /// forward, adjoint (the backward sweep and the initial state's adjoint) and, with an FFRF
  /// design body, reduction (0 when the design's factors did not change) and reduction_adjoint.
  std::vector<optimize::Timing> timings() const override;
  /// Solve every step with Newton's method proper (reuse 0) or with kept matrices
  /// (time.newton_reuse, the default). check-gradient uses 0: kept-matrix iterations stop within
  /// their tolerance at a point that depends on when the matrix was renewed, which leaves about
  /// 1e-10 relative noise in the responses of a 2,000-step run (docs/theory.md section 9.5),
  /// above what a finite difference of a single element resolves.
  void set_newton_reuse(double reuse) { integration_.newton.reuse_contraction = reuse; }
  /// Newton's method proper (set_newton_reuse(0)) and the filter's solves to round-off; names
  /// the user's options that loosen the filter or the FFRF reduction's eigen solve (-eps_tol).
  std::vector<std::string> solve_to_round_off() override;
  /// Random starts for the filter's solves only when the user's options loosened them: every
  /// other solve is direct or Newton's, whatever its start.
  bool set_random_start(unsigned long seed) override;
  /// The scene, its design body with the mass of the last evaluation's design.
  dynamics::Scene &scene() { return scene_; }
  double forward_seconds() const { return forward_s_; }
  double adjoint_seconds() const { return adjoint_s_; }
  /// Main steps recomputed from checkpoints by the last evaluation with gradients.
  long long recomputed_steps() const { return recomputed_; }

private:
  template <class State, class Trace> friend class detail::PassRun;
  friend class detail::DensePass;
  friend class detail::DistPass;
  DynamicProblem() = default;
  /// Design body k (the Design's field k) placed in the scene: its indices, model and design
  /// data; `first`: the FFRF body's first design's factors.
  void bind_design_body(std::size_t k, const reduce::ElementFactors &first);
  /// A mass bound that even empty design regions exceed is refused (collective error).
  void check_mass_bounds() const;
  /// The responses' names, sensors, strain-energy bodies and the sensors on FFRF design bodies;
  /// refuses responses the design bodies' models cannot serve (collective errors).
  void bind_responses();
  /// Response r's stress on an FFRF or ACF body (none for other types): refused on a rigid
  /// body with its location.
  void bind_stress(const optimize::ResponseSettings &r);
  /// The design body of case body b (null: none).
  DesignBody *design_of(int b) {
    return b >= 0 && design_of_body_[static_cast<std::size_t>(b)] >= 0
               ? &designs_[static_cast<std::size_t>(design_of_body_[static_cast<std::size_t>(b)])]
               : nullptr;
  }
  const DesignBody *design_of(int b) const {
    return const_cast<DynamicProblem *>(this)->design_of(b);
  }
  /// Whether FFRF design body db has initial elastic fields (its placed state depends on its
  /// design, section 10.2).
  bool given_fields(const DesignBody &db) const;
  /// Whether response i is a mass that counts design body db.
  bool counts_mass(std::size_t i, const DesignBody &db) const;
  /// The mass of the case's body `name` at the last design.
  double body_mass(const std::string &name) const;
  /// A rigid design body's mass parameters theta from its mass factors, the body replaced.
  void set_rigid_design(DesignBody &db);
  /// The FFRF design body's reduction made again if its factors changed.
  void set_ffrf_design(DesignBody &db);
  /// After a forward run of `seconds`: the run's figures and the response values into `out`
  /// (section 9.3).
  void finish_forward(double seconds, bool gradients, optimize::Evaluation &out);
  /// The gradients dPsi/d(physical density) of the last evaluation pulled back through the
  /// projection and the filter to the design variables (sections 4 and 5), into `out`; warns
  /// once of a response that the densities cannot move.
  void pull_back(optimize::Evaluation &out);
  /// Every rigid and FFRF design body's element gradients from the stacked G = dPsi/dtheta
  /// (design_partials' rows; one column per response) and the start's sensitivities.
  void add_element_gradients(const Matrix &G, const StartAdjoint &start);
  /// db.ev.element_gradient += dPsi/dw_e = G . theta_e (and the body's own mass) times dw_e,
  /// from G = dPsi/dtheta (10 x responses).
  void add_rigid_element_gradients(DesignBody &db, const Matrix &G);
  /// The FFRF design body (section 10): element_gradient += ds_e s_hat_e + dw_e w_hat_e from
  /// G = (d r/d model)^T mu summed over the steps (packed FfrfModel cotangents, one column per
  /// response), the damping's Rayleigh split, the mass response and the sensors' bases.
  /// `start`: the start's sensitivities to the placed state (section 9.2 item 6), used when the
  /// design body has initial elastic fields (section 10.2).
  void add_ffrf_element_gradients(DesignBody &db, const Matrix &G, const StartAdjoint &start);
  /// dPsi/dS of response i's sensor on the FFRF design body (its basis at the point, S =
  /// Psi(X_s)) as basis cotangents added to c (n vectors, kept in `owned`); false if zero.
  bool add_sensor_cotangent(const DesignBody &db, std::size_t i, int n,
                            reduce::ReductionCotangent &c, std::vector<Vec> &owned) const;
  /// The initial elastic fields' part of response i's cotangent (section 10.2): the start's
  /// sensitivities to the placed elastic coordinates and rates, the positions' metric, and the
  /// projections' element terms into `projection_w`.
  void add_initial_field_cotangent(const DesignBody &db, std::size_t i, int n,
                                   const StartAdjoint &start, reduce::ReductionCotangent &c,
                                   std::vector<Vec> &owned,
                                   std::vector<double> &projection_w) const;
  /// If response i's sensor reads an FFRF design body: its frame (the body's rotation, or the
  /// identity for an elastic displacement) and elastic coordinates at the mechanism's (or small
  /// part's) coordinates q, for the sensor's basis cotangent (section 10).
  void record_design_frame(std::size_t i, const Vector &q);
  /// Rows of the stacked design partials: per rigid or FFRF design body 10 mass parameters or
  /// its packed FfrfModel (0: only ACF design bodies).
  int design_parameters() const;
  /// The rows of design body db's block: 10 (rigid) or its packed FfrfModel's size (FFRF).
  int design_parameters_of(const DesignBody &db) const;
  /// (d r/d theta)^T W for the rigid and FFRF design bodies' blocks of W, stacked in the order
  /// of designs_ (ResidualPartials; docs/theory.md 9.9).
  Matrix design_partials(const Vector &q, const Vector &v, const Vector &a, bool gravity,
                         const Matrix &W) const;
  /// Which main steps the forward run stores (all, or step 0, the binomial schedule's first
  /// descent and the last step, with the schedule).
  std::vector<char> plan_checkpoints(std::unique_ptr<BinomialSchedule> &schedule) const;
  /// This rank's checkpoint file of `storage: disk`.
  std::string checkpoint_file() const;
  /// Once per run, before the forward run stores its states in memory: `states` records of
  /// `bytes` each on this rank (the first one measured) against the memory available on each
  /// node (MemAvailable); prints the estimate, and refuses (a collective flexopt::Error naming
  /// adjoint.checkpoints with the N that fits, or storage: disk) above 80 % of it. Collective.
  void check_checkpoint_memory(long long bytes, long long states);
  bool checkpoint_memory_checked_ = false;
  /// The value of response i at the last evaluation.
  double response_value(std::size_t i) const;

  // What lasts the whole run (create).
  DynamicSettings settings_;
  dynamics::IntegratorSettings integration_; ///< the forward runs' (IntegratorSettings::from)
  long long steps_ = 0;                      ///< main steps of a run
  std::string scratch_;                      ///< the directory of the checkpoint file
  dynamics::Scene scene_;
  std::unique_ptr<optimize::Design> design_;
  std::vector<DesignBody> designs_; ///< in the order of `design:` (the Design's fields)
  std::vector<int> design_of_body_; ///< per case body: its index in designs_, or -1
  bool ffrf_design_ = false;        ///< some design body is an FFRF body
  StepObserver observer_;
  reduce::BasisDerivative basis_ = reduce::BasisDerivative::Exact;
  // The responses: objective, then constraints.
  std::vector<const optimize::ResponseSettings *> specs_;
  std::vector<std::string> names_;
  std::vector<int> sensor_of_; ///< per response: index in scene_.sensors (-1: none)
  /// Per response: the FFRF design body (index in designs_) whose basis its sensor reads (its
  /// BoundSensor holds the point's location), or -1.
  std::vector<int> sensor_design_;
  /// Per response: the FFRF bodies (mechanism indices) whose strain energies it integrates, and
  /// the ACF bodies (indices among the scene's ACF bodies).
  std::vector<std::vector<int>> strain_bodies_, acf_strain_bodies_;
  /// Per response: a stress response on an FFRF or ACF body (null: none) and that body's
  /// index in the mechanism (FFRF) or among the scene's ACF bodies (ACF), and in the case
  /// (docs/theory.md 8.3, 10.3).
  std::vector<std::unique_ptr<BodyStress>> stress_;
  std::vector<int> stress_body_, stress_case_body_;
  /// Response i's stress as an FFRF body's or an ACF body's (null: neither).
  FfrfStress *ffrf_stress(std::size_t i) const {
    return dynamic_cast<FfrfStress *>(stress_[i].get());
  }
  AcfStress *acf_stress(std::size_t i) const { return dynamic_cast<AcfStress *>(stress_[i].get()); }
  bool filter_limited_ = false; ///< the user's options loosen the filter's solves
  // Figures over the run (describe, timings).
  long long evaluations_ = 0;
  /// Wall times of the last evaluation with gradients (forward, backward sweep), of all
  /// forward runs, and of the last reduction and its adjoint.
  double forward_s_ = 0, adjoint_s_ = 0, forward_total_s_ = 0;
  /// The last backward sweep's recomputed main steps, checkpoint bytes (peak, all ranks) and
  /// factorizations.
  long long recomputed_ = 0, checkpoint_bytes_ = 0, adjoint_factorizations_ = 0;

  /// What one evaluation computes (the last one's; evaluate starts it anew).
  struct Evaluated {
    std::vector<std::vector<double>> substep_sizes; ///< per main step: the halved step's sizes
    std::vector<std::vector<Vec3>> samples;         ///< per response: y_n (trajectory responses)
    std::vector<SampledResponse> sampled;
    /// Per response on an FFRF design body: per main step the sensor's frame rotation A_n and
    /// elastic coordinates zeta_n, for dPsi/dS = sum_n A_n^T dPsi/dy_n zeta_n^T.
    std::vector<std::vector<std::pair<bodies::Mat3, Vector>>> sensor_frames;
    /// The parts of the evaluation's wall time (timings(); the reductions' are the bodies').
    double forward_s = 0, adjoint_s = 0;
  } ev_;
};

} // namespace flexopt::adjoint
