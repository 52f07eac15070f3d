// One design under several conditions, run on groups of ranks (docs/theory.md section 13).
#include "flexopt/optimize/scenario_problem.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <set>

namespace flexopt::optimize {

namespace {

double max_over(MPI_Comm comm, double v) {
  MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, MPI_MAX, comm);
  return v;
}

/// Copies a's local values into b (vectors of the same local size on different communicators).
void copy_local(Vec a, Vec b) {
  PetscInt n = 0, m = 0;
  FX_PETSC(VecGetLocalSize(a, &n));
  FX_PETSC(VecGetLocalSize(b, &m));
  if (n != m) throw Error("scenarios: group vectors of different local sizes", true);
  const PetscScalar *av = nullptr;
  PetscScalar *bv = nullptr;
  FX_PETSC(VecGetArrayRead(a, &av));
  FX_PETSC(VecGetArray(b, &bv));
  std::copy(av, av + n, bv);
  FX_PETSC(VecRestoreArray(b, &bv));
  FX_PETSC(VecRestoreArrayRead(a, &av));
}

/// Runs f (a group's work), then agrees over comm: an Error thrown on some ranks (collective
/// over their group only) is thrown again on every rank of comm, with the message of the lowest
/// failing rank, so that the other groups never wait in a collective call.
void agree(MPI_Comm comm, const std::function<void()> &f) {
  std::string message;
  int failed = 0;
  try {
    f();
  } catch (const Error &e) {
    message = e.what();
    failed = 1;
  }
  const int ranks = comm_size(comm), rank = comm_rank(comm);
  int first = failed ? rank : ranks;
  MPI_Allreduce(MPI_IN_PLACE, &first, 1, MPI_INT, MPI_MIN, comm);
  if (first == ranks) return;
  int length = static_cast<int>(message.size());
  MPI_Bcast(&length, 1, MPI_INT, first, comm);
  message.resize(static_cast<std::size_t>(length));
  MPI_Bcast(message.data(), length, MPI_CHAR, first, comm);
  throw Error(message, true);
}

/// The group of rank r among `groups` contiguous blocks of `ranks` (sizes differ by at most 1).
int group_of_rank(int r, int ranks, int groups) {
  return static_cast<int>(static_cast<long long>(r) * groups / ranks);
}

} // namespace

Combined combine_values(const ScenarioUse &use, const std::vector<double> &f, double scale) {
  Combined c;
  c.df.assign(f.size(), 1.0);
  switch (use.combine) {
  case Combine::Sum:
    for (double v : f) c.value += v;
    break;
  case Combine::Weighted:
    for (std::size_t k = 0; k < f.size(); ++k) {
      c.value += use.weights[k] * f[k];
      c.df[k] = use.weights[k];
    }
    break;
  case Combine::Max: {
    // KS with the largest value factored out (no overflow): m + (s/k) ln sum exp(k (f - m)/s).
    const double m = *std::max_element(f.begin(), f.end());
    double sum = 0;
    for (std::size_t k = 0; k < f.size(); ++k) {
      c.df[k] = std::exp(use.ks * (f[k] - m) / scale);
      sum += c.df[k];
    }
    for (double &d : c.df) d /= sum;
    c.value = m + scale / use.ks * std::log(sum);
    break;
  }
  }
  return c;
}

std::unique_ptr<ScenarioProblem> ScenarioProblem::create(MPI_Comm comm,
                                                         const ScenarioSettings &settings,
                                                         const ConditionFactory &condition,
                                                         const DesignFactory &design) {
  std::unique_ptr<ScenarioProblem> p(new ScenarioProblem());
  p->comm_ = comm;
  p->settings_ = settings;
  const int ranks = comm_size(comm), rank = comm_rank(comm);
  const int conditions = static_cast<int>(settings.names.size());
  int groups = std::min(ranks, conditions);
  if (settings.groups > 0) groups = std::min(groups, settings.groups);
  p->groups_ = std::max(1, groups);
  p->group_ = group_of_rank(rank, ranks, p->groups_);
  MPI_Comm_split(comm, p->group_, rank, &p->group_comm_);
  p->leader_ = comm_rank(p->group_comm_) == 0;
  // The split, a line per group: its ranks and its conditions.
  const std::string plural = settings.noun + "s";
  print0(comm, "%s: %d on %d rank(s) in %d group(s)%s\n", plural.c_str(), conditions, ranks,
         p->groups_,
         p->groups_ < conditions ? (" (a group runs its " + plural + " one after another)").c_str()
                                 : "");
  for (int g = 0; g < p->groups_; ++g) {
    int first = ranks, last = -1;
    for (int r = 0; r < ranks; ++r)
      if (group_of_rank(r, ranks, p->groups_) == g) {
        first = std::min(first, r);
        last = r;
      }
    std::string names;
    for (int k = g; k < conditions; k += p->groups_)
      names += (names.empty() ? "" : ", ") + settings.names[static_cast<std::size_t>(k)];
    if (first == last)
      print0(comm, "  group %d, rank %d: %s\n", g, first, names.c_str());
    else
      print0(comm, "  group %d, ranks %d-%d: %s\n", g, first, last, names.c_str());
  }
  const std::size_t n = settings.responses.size();
  for (std::size_t k = static_cast<std::size_t>(p->group_); k < settings.names.size();
       k += static_cast<std::size_t>(p->groups_)) {
    p->mine_.emplace_back();
    Condition &c = p->mine_.back();
    c.index = k;
    for (std::size_t i = 0; i < n; ++i) {
      const auto &s = settings.responses[i].scenarios;
      if (std::find(s.begin(), s.end(), k) != s.end()) c.responses.push_back(i);
    }
  }
  agree(comm, [&] {
    for (Condition &c : p->mine_) {
      if (c.responses.empty())
        throw Error(settings.noun + " '" + settings.names[c.index] + "': no response takes it",
                    true);
      const PrintPrefix prefix("[" + settings.names[c.index] + "] ");
      try {
        c.problem = condition(p->group_comm_, c.index, c.responses);
      } catch (const Error &e) {
        throw Error(settings.noun + " '" + settings.names[c.index] + "': " + e.what(), true);
      }
    }
  });
  if (p->groups_ == 1) {
    p->design_ = &p->mine_.front().problem->design();
  } else {
    p->own_ = design(comm);
    p->design_ = p->own_.get();
    p->build_map();
  }
  // The conditions of a group share its design layout (one reduction over all ranks).
  int same = 1;
  for (const Condition &c : p->mine_)
    same = same && c.problem->design_keys() == p->mine_.front().problem->design_keys();
  MPI_Allreduce(MPI_IN_PLACE, &same, 1, MPI_INT, MPI_LAND, comm);
  if (!same)
    throw Error("scenarios: the design variables of the scenarios differ (their meshes)", true);
  p->values_.assign(settings.names.size(),
                    std::vector<double>(n, std::numeric_limits<double>::quiet_NaN()));
  p->ks_scale_.assign(n, 0.0);
  // The parts' names before the first evaluation (history.csv's header).
  p->timings_ = p->mine_.front().problem->timings();
  for (Timing &t : p->timings_) t.seconds = 0;
  return p;
}

ScenarioProblem::~ScenarioProblem() {
  VecDestroy(&xg_);
  VecDestroy(&yg_);
  VecDestroy(&y_);
  VecScatterDestroy(&scatter_);
  mine_.clear(); // before their communicator
  if (group_comm_ != MPI_COMM_NULL) MPI_Comm_free(&group_comm_);
}

void ScenarioProblem::build_map() {
  // Every key of the design on comm_ with its global index (ranks own contiguous ranges in rank
  // order), sorted; each group variable's index found by its key.
  const std::vector<std::uint64_t> &keys = design_->design_keys();
  const int ranks = comm_size(comm_);
  int local = static_cast<int>(keys.size());
  std::vector<int> counts(static_cast<std::size_t>(ranks)), displs(static_cast<std::size_t>(ranks));
  MPI_Allgather(&local, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_);
  int total = 0;
  for (int r = 0; r < ranks; ++r) {
    displs[static_cast<std::size_t>(r)] = total;
    total += counts[static_cast<std::size_t>(r)];
  }
  std::vector<std::uint64_t> all(static_cast<std::size_t>(total));
  MPI_Allgatherv(keys.data(), local, MPI_UINT64_T, all.data(), counts.data(), displs.data(),
                 MPI_UINT64_T, comm_);
  std::vector<std::pair<std::uint64_t, PetscInt>> sorted(all.size());
  for (std::size_t i = 0; i < all.size(); ++i) sorted[i] = {all[i], static_cast<PetscInt>(i)};
  std::sort(sorted.begin(), sorted.end());
  const std::vector<std::uint64_t> &mine = mine_.front().problem->design_keys();
  std::vector<PetscInt> from(mine.size());
  int missing = 0;
  for (std::size_t i = 0; i < mine.size(); ++i) {
    auto it = std::lower_bound(sorted.begin(), sorted.end(),
                               std::pair<std::uint64_t, PetscInt>{mine[i], 0});
    if (it == sorted.end() || it->first != mine[i]) {
      missing = 1;
      continue;
    }
    from[i] = it->second;
  }
  MPI_Allreduce(MPI_IN_PLACE, &missing, 1, MPI_INT, MPI_LOR, comm_);
  if (missing)
    throw Error("scenarios: a group's design variables are not the design's (different meshes)",
                true);
  const PetscInt ng = static_cast<PetscInt>(mine.size());
  FX_PETSC(VecCreateMPI(comm_, ng, PETSC_DETERMINE, &y_));
  PetscInt start = 0, end = 0;
  FX_PETSC(VecGetOwnershipRange(y_, &start, &end));
  IS is_from = nullptr, is_to = nullptr;
  FX_PETSC(ISCreateGeneral(comm_, ng, from.data(), PETSC_COPY_VALUES, &is_from));
  FX_PETSC(ISCreateStride(comm_, ng, start, 1, &is_to));
  Vec x = design_->create_design_vector();
  FX_PETSC(VecScatterCreate(x, is_from, y_, is_to, &scatter_));
  FX_PETSC(VecDestroy(&x));
  FX_PETSC(ISDestroy(&is_from));
  FX_PETSC(ISDestroy(&is_to));
  xg_ = mine_.front().problem->create_design_vector();
  yg_ = mine_.front().problem->create_design_vector();
}

void ScenarioProblem::to_group(Vec x) {
  FX_PETSC(VecScatterBegin(scatter_, x, y_, INSERT_VALUES, SCATTER_FORWARD));
  FX_PETSC(VecScatterEnd(scatter_, x, y_, INSERT_VALUES, SCATTER_FORWARD));
  copy_local(y_, xg_);
}

void ScenarioProblem::from_group(Vec yg, Vec g) {
  copy_local(yg, y_);
  FX_PETSC(VecScatterBegin(scatter_, y_, g, ADD_VALUES, SCATTER_REVERSE));
  FX_PETSC(VecScatterEnd(scatter_, y_, g, ADD_VALUES, SCATTER_REVERSE));
}

int ScenarioProblem::local_response(const Condition &c, std::size_t i) const {
  for (std::size_t j = 0; j < c.responses.size(); ++j)
    if (c.responses[j] == i) return static_cast<int>(j);
  return -1;
}

void ScenarioProblem::evaluate(Vec x, bool gradients, Evaluation &out) {
  const std::size_t n = settings_.responses.size(), conditions = settings_.names.size();
  const std::vector<double> betas = design_->betas();
  for (Condition &c : mine_) c.problem->design().set_betas(betas);
  Vec xin = x;
  if (groups_ > 1) {
    design_->update(x); // the optimizer's view: its densities, volume fractions
    to_group(x);
    xin = xg_;
  }
  agree(comm_, [&] {
    for (Condition &c : mine_) {
      const PrintPrefix prefix("[" + settings_.names[c.index] + "] ");
      try {
        c.problem->evaluate(xin, gradients, c.ev);
      } catch (const Error &e) {
        throw Error(settings_.noun + " '" + settings_.names[c.index] + "': " + e.what(), true);
      }
    }
  });
  // Every condition's values on every rank: one reduction (each group's leader contributes).
  std::vector<double> buf(conditions * n, 0.0);
  if (leader_)
    for (const Condition &c : mine_)
      for (std::size_t j = 0; j < c.responses.size(); ++j)
        buf[c.index * n + c.responses[j]] = c.ev.value(j);
  MPI_Allreduce(MPI_IN_PLACE, buf.data(), static_cast<int>(buf.size()), MPI_DOUBLE, MPI_SUM, comm_);
  out.constraints.assign(n - 1, 0.0);
  std::vector<std::vector<double>> coef(n, std::vector<double>(conditions, 0.0));
  for (std::size_t i = 0; i < n; ++i) {
    const ScenarioUse &use = settings_.responses[i];
    std::vector<double> f;
    for (std::size_t k : use.scenarios) {
      values_[k][i] = buf[k * n + i];
      f.push_back(values_[k][i]);
    }
    if (use.combine == Combine::Max && ks_scale_[i] == 0) {
      // The KS reference: the largest |value| at the first design (docs/theory.md 13.2).
      double s = 0;
      for (double v : f) s = std::max(s, std::abs(v));
      ks_scale_[i] = s > 0 ? s : 1.0;
    }
    const Combined cb = combine_values(use, f, ks_scale_[i] > 0 ? ks_scale_[i] : 1.0);
    out.value(i) = cb.value;
    for (std::size_t m = 0; m < use.scenarios.size(); ++m) coef[i][use.scenarios[m]] = cb.df[m];
  }
  // Timings: per part, each group's sum over its conditions, the largest over the groups.
  // (the names are the same in every condition: the same bodies' models)
  for (Timing &t : timings_) t.seconds = 0;
  for (const Condition &c : mine_) {
    const std::vector<Timing> tc = c.problem->timings();
    for (std::size_t t = 0; t < timings_.size() && t < tc.size(); ++t)
      timings_[t].seconds += tc[t].seconds;
  }
  for (Timing &t : timings_) t.seconds = max_over(comm_, t.seconds);
  if (!gradients) return;
  if (!out.d_objective) {
    out.d_objective = create_design_vector();
    for (std::size_t i = 1; i < n; ++i) out.d_constraints.push_back(create_design_vector());
  }
  for (std::size_t i = 0; i < n; ++i) {
    Vec target = groups_ > 1 ? yg_ : out.gradient(i);
    FX_PETSC(VecSet(target, 0.0));
    for (const Condition &c : mine_) {
      const int j = local_response(c, i);
      if (j >= 0)
        FX_PETSC(VecAXPY(target, coef[i][c.index], c.ev.gradient(static_cast<std::size_t>(j))));
    }
    if (groups_ > 1) {
      FX_PETSC(VecSet(out.gradient(i), 0.0));
      from_group(yg_, out.gradient(i));
    }
  }
}

io::GridLayout ScenarioProblem::design_layout() const {
  if (groups_ == 1) return mine_.front().problem->design_layout();
  // Several design bodies sit where the first scenario's scene places them.
  const auto placed = share([](const Condition &c) {
    std::vector<double> flat;
    for (const auto &pl : c.problem->design_placements())
      flat.insert(flat.end(), pl.begin(), pl.end());
    return flat;
  });
  const std::vector<double> &flat = placed.front();
  if (flat.empty()) return design_->grid_layout();
  std::vector<std::array<double, 12>> placements(flat.size() / 12);
  for (std::size_t k = 0; k < placements.size(); ++k)
    std::copy(flat.begin() + static_cast<long>(12 * k),
              flat.begin() + static_cast<long>(12 * k + 12), placements[k].begin());
  return design_->grid_layout(design_->placed_coordinates(placements));
}

std::vector<std::vector<double>>
ScenarioProblem::share(const std::function<std::vector<double>(const Condition &)> &of) const {
  // Collective over comm_: each group computes its conditions' vectors (collectively over the
  // group), its leader contributes them to two reductions (the sizes, then the values).
  const std::size_t conditions = settings_.names.size();
  std::vector<std::vector<double>> mine(conditions);
  for (const Condition &c : mine_) mine[c.index] = of(c);
  std::vector<long long> sizes(conditions, 0);
  if (leader_)
    for (const Condition &c : mine_) sizes[c.index] = static_cast<long long>(mine[c.index].size());
  MPI_Allreduce(MPI_IN_PLACE, sizes.data(), static_cast<int>(conditions), MPI_LONG_LONG, MPI_SUM,
                comm_);
  std::vector<std::size_t> offset(conditions + 1, 0);
  for (std::size_t k = 0; k < conditions; ++k)
    offset[k + 1] = offset[k] + static_cast<std::size_t>(sizes[k]);
  std::vector<double> flat(offset.back(), 0.0);
  if (leader_)
    for (const Condition &c : mine_)
      std::copy(mine[c.index].begin(), mine[c.index].end(),
                flat.begin() + static_cast<long>(offset[c.index]));
  MPI_Allreduce(MPI_IN_PLACE, flat.data(), static_cast<int>(flat.size()), MPI_DOUBLE, MPI_SUM,
                comm_);
  std::vector<std::vector<double>> out(conditions);
  for (std::size_t k = 0; k < conditions; ++k)
    out[k].assign(flat.begin() + static_cast<long>(offset[k]),
                  flat.begin() + static_cast<long>(offset[k + 1]));
  return out;
}

void ScenarioProblem::describe(io::Json &summary) const {
  // summary.json is written by rank 0 (in group 0, which has condition 0): condition 0's figures
  // at the top level as a single problem's, and every condition's under "scenarios", the other
  // groups' sent to rank 0 as text.
  const int rank = comm_rank(comm_);
  io::Json per = io::Json::object();
  for (std::size_t k = 0; k < settings_.names.size(); ++k) {
    const int g = group_of(k);
    std::string text;
    if (g == group_) {
      const Condition &c = *std::find_if(mine_.begin(), mine_.end(),
                                         [&](const Condition &m) { return m.index == k; });
      io::Json one = io::Json::object();
      c.problem->describe(one);
      if (k == 0) c.problem->describe(summary);
      if (rank == 0) per[settings_.names[k]] = one;
      text = one.dump();
      if (leader_ && rank != 0) {
        MPI_Send(text.data(), static_cast<int>(text.size()), MPI_CHAR, 0, static_cast<int>(k),
                 comm_);
      }
    } else if (rank == 0) {
      MPI_Status st;
      MPI_Probe(MPI_ANY_SOURCE, static_cast<int>(k), comm_, &st);
      int len = 0;
      MPI_Get_count(&st, MPI_CHAR, &len);
      text.resize(static_cast<std::size_t>(len));
      MPI_Recv(text.data(), len, MPI_CHAR, st.MPI_SOURCE, static_cast<int>(k), comm_,
               MPI_STATUS_IGNORE);
      per[settings_.names[k]] = io::Json::serialized(text);
    }
  }
  io::Json split = io::Json::array();
  const int ranks = comm_size(comm_);
  for (std::size_t k = 0; k < settings_.names.size(); ++k) {
    io::Json s = io::Json::object();
    s["name"] = settings_.names[k];
    s["group"] = group_of(k);
    io::Json rs = io::Json::array();
    for (int r = 0; r < ranks; ++r)
      if (group_of_rank(r, ranks, groups_) == group_of(k)) rs.push_back(r);
    s["ranks"] = rs;
    split.push_back(s);
  }
  summary["scenario_groups"] = groups_;
  summary["scenario_split"] = split;
  summary["scenarios"] = per;
  // The last evaluation's values per condition and response.
  io::Json values = io::Json::object();
  for (std::size_t k = 0; k < settings_.names.size(); ++k) {
    io::Json row = io::Json::object();
    for (std::size_t i = 0; i < settings_.response_names.size(); ++i)
      if (!std::isnan(values_[k][i])) row[settings_.response_names[i]] = values_[k][i];
    values[settings_.names[k]] = row;
  }
  summary["scenario_responses"] = values;
}

std::vector<Timing> ScenarioProblem::timings() const {
  return timings_;
}

long long ScenarioProblem::dofs() const {
  long long d = 0;
  for (const Condition &c : mine_) d = std::max(d, c.problem->dofs());
  MPI_Allreduce(MPI_IN_PLACE, &d, 1, MPI_LONG_LONG, MPI_MAX, comm_);
  return d;
}

double ScenarioProblem::noise_floor() const {
  double v = 0;
  for (const Condition &c : mine_) v = std::max(v, c.problem->noise_floor());
  return max_over(comm_, v);
}

double ScenarioProblem::largest(std::size_t i, PerResponse of) const {
  double v = 0;
  for (const Condition &c : mine_) {
    const int j = local_response(c, i);
    if (j >= 0) v = std::max(v, ((*c.problem).*of)(static_cast<std::size_t>(j)));
  }
  return max_over(comm_, v);
}

double ScenarioProblem::noise_floor(std::size_t i) const {
  return largest(i, static_cast<PerResponse>(&DesignProblem::noise_floor));
}

double ScenarioProblem::fd_step() const {
  double v = 0;
  for (const Condition &c : mine_) v = std::max(v, c.problem->fd_step());
  return max_over(comm_, v);
}

int ScenarioProblem::fd_levels() const {
  double v = 0;
  for (const Condition &c : mine_) v = std::max(v, static_cast<double>(c.problem->fd_levels()));
  return static_cast<int>(max_over(comm_, v));
}

double ScenarioProblem::round_off_level(std::size_t i) const {
  return largest(i, &DesignProblem::round_off_level);
}

std::vector<std::string> ScenarioProblem::solve_to_round_off() {
  std::set<std::string> seen;
  std::vector<std::string> out;
  for (Condition &c : mine_)
    for (const std::string &s : c.problem->solve_to_round_off())
      if (seen.insert(s).second) out.push_back(s);
  return out;
}

bool ScenarioProblem::set_random_start(unsigned long seed) {
  int any = 0;
  for (Condition &c : mine_) any = c.problem->set_random_start(seed) || any;
  MPI_Allreduce(MPI_IN_PLACE, &any, 1, MPI_INT, MPI_LOR, comm_);
  return any != 0;
}

void ScenarioProblem::end_iteration() {
  for (Condition &c : mine_) c.problem->end_iteration();
}

std::vector<double> ScenarioProblem::response_scales() const {
  const auto per = share([](const Condition &c) { return c.problem->response_scales(); });
  std::vector<double> out;
  for (const auto &v : per) out.insert(out.end(), v.begin(), v.end());
  out.insert(out.end(), ks_scale_.begin(), ks_scale_.end());
  return out;
}

void ScenarioProblem::restore_response_scales(const std::vector<double> &scales) {
  const auto per = share([](const Condition &c) { return c.problem->response_scales(); });
  std::size_t at = 0;
  for (std::size_t k = 0; k < per.size(); ++k) {
    const std::vector<double> part(scales.begin() + static_cast<long>(at),
                                   scales.begin() + static_cast<long>(at + per[k].size()));
    for (Condition &c : mine_)
      if (c.index == k) c.problem->restore_response_scales(part);
    at += per[k].size();
  }
  if (scales.size() != at + ks_scale_.size())
    throw Error("restart: the response scales do not match the case's scenarios", true);
  std::copy(scales.begin() + static_cast<long>(at), scales.end(), ks_scale_.begin());
}

std::vector<std::pair<std::string, std::vector<double>>> ScenarioProblem::cell_fields() const {
  std::vector<std::pair<std::string, std::vector<double>>> out;
  if (groups_ > 1) return out;
  for (const Condition &c : mine_)
    for (auto &f : c.problem->cell_fields())
      out.emplace_back(f.first + "." + settings_.names[c.index], std::move(f.second));
  return out;
}

std::vector<std::string> ScenarioProblem::cell_field_names() const {
  std::vector<std::string> out;
  if (groups_ > 1) return out;
  for (const Condition &c : mine_)
    for (const std::string &f : c.problem->cell_field_names())
      out.push_back(f + "." + settings_.names[c.index]);
  return out;
}

} // namespace flexopt::optimize
