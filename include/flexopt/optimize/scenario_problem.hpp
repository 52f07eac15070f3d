#pragma once
/// \file One design under several operating conditions (docs/theory.md section 13): a dynamic
/// case's scenarios or a static case's load cases, each a design problem of its own, run
/// concurrently on groups of ranks (MPI_Comm_split) or one after another. Each response of the
/// whole problem combines its conditions' values by a sum, a weighted sum or a KS maximum; its
/// gradient is the same combination of theirs. The optimizer sees one DesignProblem.
#include "flexopt/optimize/design_problem.hpp"
#include "flexopt/optimize/response.hpp"

#include <functional>
#include <list>
#include <memory>
#include <mpi.h>
#include <string>
#include <vector>

namespace flexopt::optimize {

/// How one response of the whole problem takes the conditions (ResponseSettings' scenarios,
/// combine, weights, combine_ks).
struct ScenarioUse {
  std::vector<std::size_t> scenarios;
  Combine combine = Combine::Sum;
  std::vector<double> weights;
  double ks = 50;
};

/// What a ScenarioProblem reads.
struct ScenarioSettings {
  std::vector<std::string> names;          ///< the conditions
  std::vector<std::string> response_names; ///< "objective:TYPE", "constraint0:TYPE", ...
  std::vector<ScenarioUse> responses;      ///< 0 the objective, i >= 1 constraint i - 1
  /// Groups of ranks; 0: min(ranks, conditions). Condition k runs on group k mod groups.
  int groups = 0;
  /// What a condition is called in messages: "scenario" (dynamic) or "load case" (static).
  std::string noun = "scenario";
};

/// The combination of response values f (one per taken condition) by `use`: the value, and its
/// derivative with respect to each f (docs/theory.md 13.2). `scale` (> 0) is the KS reference.
struct Combined {
  double value = 0;
  std::vector<double> df;
};
Combined combine_values(const ScenarioUse &use, const std::vector<double> &f, double scale);

class ScenarioProblem : public DesignProblem {
public:
  /// The design problem of condition k on `comm` whose responses are the whole problem's
  /// `responses` (indices, in order: the first is its objective). Collective over comm.
  using ConditionFactory = std::function<std::unique_ptr<DesignProblem>(
      MPI_Comm comm, std::size_t k, const std::vector<std::size_t> &responses)>;
  /// The design alone (its bodies' meshes and fields) on `comm`: the optimizer's view of the
  /// design when the conditions run on groups of ranks. Collective over comm.
  using DesignFactory = std::function<std::shared_ptr<Design>(MPI_Comm comm)>;

  /// Splits `comm` into the groups, prints the split, builds each group's conditions and the
  /// map between the design's layout on `comm` and each group's. Collective.
  static std::unique_ptr<ScenarioProblem> create(MPI_Comm comm, const ScenarioSettings &settings,
                                                 const ConditionFactory &condition,
                                                 const DesignFactory &design);
  ~ScenarioProblem() override;

  Design &design() override { return *design_; }
  const Design &design() const override { return *design_; }
  io::GridLayout design_layout() const override;
  const std::vector<std::string> &response_names() const override {
    return settings_.response_names;
  }
  void evaluate(Vec x, bool gradients, Evaluation &out) override;
  /// The first condition's figures, and per condition its own under "scenarios".
  void describe(io::Json &summary) const override;
  /// Per part, the largest over the groups of each group's sum over its conditions.
  std::vector<Timing> timings() const override;
  long long dofs() const override;
  double noise_floor() const override;
  double noise_floor(std::size_t i) const override;
  double fd_step() const override;
  int fd_levels() const override;
  double round_off_level(std::size_t i) const override;
  std::vector<std::string> solve_to_round_off() override;
  bool set_random_start(unsigned long seed) override;
  void end_iteration() override;
  /// The conditions' scales (each group's, shared over the ranks), then the KS references.
  std::vector<double> response_scales() const override;
  void restore_response_scales(const std::vector<double> &scales) override;
  /// The conditions' cell fields, each name followed by ".CONDITION" (one group only).
  std::vector<std::pair<std::string, std::vector<double>>> cell_fields() const override;
  std::vector<std::string> cell_field_names() const override;

  /// The groups (ranks per group, in rank order) and the group of condition k.
  int groups() const { return groups_; }
  int group_of(std::size_t k) const {
    return static_cast<int>(k % static_cast<std::size_t>(groups_));
  }
  /// The conditions' last values per response (rows: conditions, columns: responses; NaN where
  /// a response does not take the condition), the same on every rank.
  const std::vector<std::vector<double>> &condition_values() const { return values_; }

private:
  ScenarioProblem() = default;
  /// One condition of this rank's group.
  struct Condition {
    std::size_t index = 0;
    std::unique_ptr<DesignProblem> problem;
    std::vector<std::size_t> responses; ///< the whole problem's responses it evaluates
    Evaluation ev;
  };
  /// The largest over the conditions that take response i of a per-response figure of theirs.
  using PerResponse = double (DesignProblem::*)(std::size_t) const;
  double largest(std::size_t i, PerResponse of) const;
  /// The local position of response i among condition c's (-1: not taken).
  int local_response(const Condition &c, std::size_t i) const;
  /// A vector of doubles per condition, made by its group, on every rank of comm_.
  std::vector<std::vector<double>>
  share(const std::function<std::vector<double>(const Condition &)> &of) const;
  /// The map of design vectors (comm_'s layout) to this group's (its conditions' layout).
  void build_map();
  void to_group(Vec x);
  /// g += the group vector yg (every group's summed), collective over comm_.
  void from_group(Vec yg, Vec g);

  MPI_Comm comm_ = MPI_COMM_NULL, group_comm_ = MPI_COMM_NULL;
  int groups_ = 1, group_ = 0;
  bool leader_ = false; ///< rank 0 of its group
  ScenarioSettings settings_;
  std::list<Condition> mine_;   ///< this group's conditions (Evaluation does not move)
  std::shared_ptr<Design> own_; ///< the design on comm_ when there are several groups
  Design *design_ = nullptr;    ///< own_, or the one group's first condition's
  /// Several groups: the design vector of this group's layout, its image on comm_ and the
  /// scatter from comm_'s layout to it.
  Vec xg_ = nullptr, y_ = nullptr, yg_ = nullptr;
  VecScatter scatter_ = nullptr;
  std::vector<std::vector<double>> values_;
  std::vector<double> ks_scale_; ///< per response: the KS reference (0: not yet set)
  std::vector<Timing> timings_;
};

} // namespace flexopt::optimize
