#include "flexopt/app/commands.hpp"

#include "app_common.hpp"
#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/probe.hpp"
#include "flexopt/fem/static_problem.hpp"
#include "flexopt/io/case.hpp"
#include "flexopt/io/json.hpp"
#include "flexopt/io/restart.hpp"
#include "flexopt/io/xdmf.hpp"
#include "flexopt/mesh/grid_layout.hpp"
#include "flexopt/mesh/load.hpp"
#include "flexopt/optimize/design_file.hpp"
#include "flexopt/optimize/optimizer.hpp"
#include "flexopt/optimize/scenario_problem.hpp"
#include "flexopt/optimize/topology_problem.hpp"
#include "flexopt/plan/plan.hpp"
#include "flexopt/reduce/craig_bampton.hpp"
#include "flexopt/reduce/modal.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <sys/resource.h>

namespace fs = std::filesystem;

namespace flexopt::app {

namespace detail {

void load_design(MPI_Comm comm, const io::Case &c, optimize::DesignProblem &design,
                 const std::string &file, Vec x) {
  optimize::check_design_file(design.design(), file);
  const io::RestartData r = io::read_restart(comm, file, design.design_keys());
  const auto it = r.fields.find("x");
  if (it == r.fields.end())
    throw Error(file + ": no design field 'x' (--design takes the restart.h5 of a run)", true);
  optimize::check_design_values(design.design(), it->second, file, "x");
  PetscScalar *a;
  FX_PETSC(VecGetArray(x, &a));
  std::copy(it->second.begin(), it->second.end(), a);
  FX_PETSC(VecRestoreArray(x, &a));
  // The projection sharpness of the run's continuation stage (meta: iteration, objective
  // scale, constraints, stage, ...).
  const auto meta = r.arrays.find("meta");
  if (meta != r.arrays.end() && meta->second.size() > 3 && design.design().stages() > 0)
    design.design().set_stage(static_cast<int>(meta->second[3]));
}

std::string write_gradients(const optimize::DesignProblem &problem, const optimize::Evaluation &e,
                            const std::string &dir) {
  const optimize::Design &d = problem.design();
  io::XdmfWriter writer(problem.design_layout(), dir, "gradient");
  writer.begin_step(0);
  std::vector<double> cells;
  for (std::size_t i = 0; i < problem.response_names().size(); ++i) {
    // Every design body's local elements in turn (Design::grid_layout), 0 outside the regions.
    cells.clear();
    const PetscScalar *g;
    Vec gv = e.gradient(i);
    FX_PETSC(VecGetArrayRead(gv, &g));
    for (std::size_t f = 0; f < d.size(); ++f) {
      const auto &elements = d.field(f).design_elements();
      const std::size_t base = cells.size();
      cells.resize(base + static_cast<std::size_t>(d.field(f).mesh().local_elements()), 0.0);
      for (std::size_t k = 0; k < elements.size(); ++k)
        cells[base + static_cast<std::size_t>(elements[k])] =
            g[static_cast<std::size_t>(d.local_offset(f)) + k];
    }
    FX_PETSC(VecRestoreArrayRead(gv, &g));
    writer.cell_scalar(i == 0 ? "gradient_objective"
                              : "gradient_constraint" + std::to_string(i - 1),
                       cells.data());
  }
  return writer.close();
}

std::string output_directory(const Context &ctx, const Options &o) {
  const std::string dir = o.out.empty() ? (fs::path(o.case_dir) / "out").string() : o.out;
  run_on_root(ctx.comm(), 0, [&] {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec || !fs::is_directory(dir)) throw Error("cannot create output directory '" + dir + "'");
    // A stale summary from an earlier run must not pass for this run's result.
    fs::remove(fs::path(dir) / "summary.json", ec);
    // The incomplete files of a run that was killed (every writer writes NAME.tmp and renames
    // it when complete): removed, and named. `optimize --restart` keeps design.h5.tmp: the
    // optimizer carries its frames over into the new design.h5.
    std::string stale;
    for (const auto &entry : fs::directory_iterator(dir, ec))
      if (entry.is_regular_file() && entry.path().extension() == ".tmp" &&
          !(o.restart && entry.path().filename() == "design.h5.tmp")) {
        stale += (stale.empty() ? "" : ", ") + entry.path().filename().string();
        fs::remove(entry.path(), ec);
      }
    if (!stale.empty())
      std::printf("output: removed %s in %s, left by an interrupted run\n", stale.c_str(),
                  dir.c_str());
  });
  return dir;
}

io::Json base_summary(const Context &ctx, const Options &o, const io::Case &c) {
  io::Json s = io::Json::object();
  s["command"] = o.command;
  s["case"] = c.name;
  s["ranks"] = ctx.size();
  if (!o.plan.is_null()) s["plan"] = o.plan;
  return s;
}

void write_summary(const Context &ctx, const std::string &dir, io::Json &s, double t0) {
  s["wall_s"] = wall_time() - t0;
  // The peak resident set of the largest rank and the sum of the ranks' (getrusage: KiB on Linux;
  // MUMPS's and Gmsh's allocations included, which PETSc's memory counters miss).
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const double own = static_cast<double>(usage.ru_maxrss) / 1024.0;
  double peak = own, total = own;
  MPI_Allreduce(MPI_IN_PLACE, &peak, 1, MPI_DOUBLE, MPI_MAX, ctx.comm());
  MPI_Allreduce(MPI_IN_PLACE, &total, 1, MPI_DOUBLE, MPI_SUM, ctx.comm());
  s["peak_memory_mib"] = peak;
  s["peak_memory_total_mib"] = total; // the ranks' peaks summed
  run_on_root(ctx.comm(), 0, [&] {
    io::write_file_atomic((fs::path(dir) / "summary.json").string(), s.dump() + "\n");
  });
}

namespace {

/// The design bodies' meshes and design fields alone on comm (a ScenarioProblem's design when
/// its conditions run on groups of ranks): the same meshes and fields the conditions build.
std::shared_ptr<optimize::Design> design_alone(MPI_Comm comm, const io::Case &c) {
  struct Held {
    std::vector<std::unique_ptr<mesh::DistributedMesh>> meshes;
    std::unique_ptr<optimize::Design> design;
  };
  auto held = std::make_shared<Held>();
  std::vector<std::unique_ptr<optimize::DesignField>> fields;
  for (const optimize::DesignSettings &d : c.design) {
    const dynamics::BodyDescription &b = c.scene.body(d.body);
    held->meshes.push_back(
        std::make_unique<mesh::DistributedMesh>(mesh::load_body_mesh(comm, b.mesh)));
    fields.push_back(std::make_unique<optimize::DesignField>(*held->meshes.back(), d));
  }
  held->design = std::make_unique<optimize::Design>(std::move(fields));
  return std::shared_ptr<optimize::Design>(held, held->design.get());
}

/// The design problem of one condition (or of a case without conditions).
std::unique_ptr<optimize::DesignProblem>
condition_problem(MPI_Comm comm, const io::Case &c, bool optimizing, const std::string &dir) {
  if (c.dynamic())
    return adjoint::DynamicProblem::create(comm, io::dynamic_settings(c), dir, optimizing);
  return optimize::TopologyProblem::create(comm, io::topology_settings(c));
}

} // namespace

std::unique_ptr<optimize::DesignProblem> create_design_problem(MPI_Comm comm, const io::Case &c,
                                                               bool optimizing,
                                                               const std::string &dir,
                                                               int scenario_groups) {
  if (io::condition_names(c).empty()) return condition_problem(comm, c, optimizing, dir);
  optimize::ScenarioSettings settings = io::scenario_settings(c);
  settings.groups = scenario_groups;
  return optimize::ScenarioProblem::create(
      comm, settings,
      [&](MPI_Comm group, std::size_t k, const std::vector<std::size_t> &responses) {
        return condition_problem(group, io::condition_case(c, k, responses), optimizing, dir);
      },
      [&](MPI_Comm world) { return design_alone(world, c); });
}

io::Json
each_condition(const Context &ctx, const io::Case &c,
               const std::function<void(const io::Case &, const std::string &, io::Json &)> &one) {
  const std::vector<std::string> names = io::condition_names(c);
  io::Json per = io::Json::object();
  for (std::size_t k = 0; k < names.size(); ++k) {
    print0(ctx.comm(), "%s %s (%zu of %zu)\n", io::condition_noun(c), names[k].c_str(), k + 1,
           names.size());
    io::Json figures = io::Json::object();
    const PrintPrefix prefix("[" + names[k] + "] ");
    one(io::condition_case(c, k, io::condition_responses(c, k)), names[k], figures);
    per[names[k]] = figures;
  }
  return per;
}

} // namespace detail

using detail::base_summary;
using detail::each_condition;
using detail::output_directory;
using detail::write_summary;

namespace {

/// Shift for the modal solve [rad^2/s^2]: negative so that K - shift M stays non-singular for
/// a free body (its rigid-body modes have omega^2 = 0).
constexpr double kModalShift = -1.0;

io::Json rank_counts(const std::vector<PetscInt> &v) {
  io::Json a = io::Json::array();
  for (PetscInt x : v) a.push_back(static_cast<long long>(x));
  return a;
}

/// Writes the owner rank of each local element as a cell field.
std::vector<double> owner_field(const mesh::DistributedMesh &m) {
  return std::vector<double>(static_cast<std::size_t>(m.local_elements()),
                             static_cast<double>(comm_rank(m.comm)));
}

/// info: the sensors on body `b` (mesh m) whose point must lie in its mesh, located now rather
/// than after a run's set-up: on a static body and on FFRF and ACF bodies an error naming the
/// sensor's line, on a body whose model the plan chooses a warning (a flexible model will need
/// the point inside); a rigid body's points may lie anywhere. Collective.
void check_sensor_points(const Context &ctx, const io::Case &c, const dynamics::BodyDescription &b,
                         const mesh::DistributedMesh &m) {
  for (const dynamics::SensorDescription &s : c.scene.sensors) {
    if (s.body != b.name || !s.joint.empty()) continue;
    if (c.dynamic() && b.model == dynamics::BodyModel::Rigid) continue;
    const std::string where = s.where.str() + ": sensor '" + s.name + "' point";
    try {
      fem::locate(m, s.point, where);
    } catch (const Error &e) { // thrown on every rank: locate agrees on the owner collectively
      if (!c.dynamic() || b.model != dynamics::BodyModel::Auto) throw;
      print0(ctx.comm(),
             "  warning: %s; body '%s' is model auto: if the plan chooses ffrf or acf, the run "
             "stops there\n",
             e.what(), b.name.c_str());
    }
  }
}

int run_info(const Context &ctx, const Options &o, const io::Case &c, double t0) {
  const std::string dir = output_directory(ctx, o);
  io::Json s = base_summary(ctx, o, c);
  s["analysis"] = c.analysis_name();
  print0(ctx.comm(), "case %s (%s), analysis: %s, %d rank(s)\n", c.name.c_str(), c.file.c_str(),
         c.analysis_name(), ctx.size());
  long long total_dofs = 0, total_elements = 0;
  io::Json bodies = io::Json::array();
  for (const auto &b : c.scene.bodies) {
    const double tb = wall_time();
    mesh::MeshEstimate est; // significant on rank 0, which prints and writes the summary
    mesh::DistributedMesh m = mesh::load_body_mesh(ctx.comm(), b.mesh, {}, &est);
    const bool geo = est.elements > 0;
    const auto elems = mesh::elements_per_rank(m), nodes = mesh::nodes_per_rank(m);
    const fem::IsotropicMaterial &mat = b.material;
    print0(ctx.comm(),
           "body %s: model %s, geometry %s, material %s (E %g Pa, nu %g, density %g kg/m^3)\n",
           b.name.c_str(), dynamics::model_name(b.model), b.mesh.geometry_key.c_str(),
           b.material_name.c_str(), mat.E, mat.nu, mat.density);
    print0(ctx.comm(),
           "  mesh: %lld %s elements, %lld nodes, %lld DOFs (meshed and distributed in %.2f s)\n",
           static_cast<long long>(m.global_elements), fem::element_name(m.type),
           static_cast<long long>(m.global_nodes), 3LL * m.global_nodes, wall_time() - tb);
    const std::int64_t limit = b.mesh.max_elements > 0
                                   ? b.mesh.max_elements
                                   : mesh::default_max_elements(b.mesh.order, est.hexahedra);
    if (geo)
      print0(ctx.comm(),
             "  estimate before meshing: %.0f %s elements, %.0f nodes (volume %.6g m^3, effective "
             "element size %.4g m; %.2f times the count); mesh.max_elements %lld\n",
             est.elements, est.element_name().c_str(), est.nodes, est.volume, est.size,
             est.elements / static_cast<double>(m.global_elements), static_cast<long long>(limit));
    std::string vols, surfs;
    for (const auto &kv : m.volume_groups) vols += " " + kv.first;
    for (const auto &kv : m.surfaces) surfs += " " + kv.first;
    print0(ctx.comm(), "  physical volumes:%s\n  physical surfaces:%s\n",
           vols.empty() ? " (none)" : vols.c_str(), surfs.empty() ? " (none)" : surfs.c_str());
    for (int r = 0; r < ctx.size(); ++r)
      print0(ctx.comm(), "  rank %d: %lld elements, %lld owned nodes\n", r,
             static_cast<long long>(elems[static_cast<std::size_t>(r)]),
             static_cast<long long>(nodes[static_cast<std::size_t>(r)]));
    io::Json jb = io::Json::object();
    jb["name"] = b.name;
    jb["model"] = dynamics::model_name(b.model);
    jb["element_type"] = fem::element_name(m.type);
    jb["elements"] = static_cast<long long>(m.global_elements);
    jb["nodes"] = static_cast<long long>(m.global_nodes);
    jb["dofs"] = 3LL * m.global_nodes;
    if (geo) {
      io::Json je = io::Json::object();
      je["elements"] = est.elements;
      je["nodes"] = est.nodes;
      je["element_type"] = est.element_name();
      je["volume"] = est.volume;
      je["size"] = est.size;
      je["max_elements"] = static_cast<long long>(limit);
      jb["estimate"] = je;
    }
    jb["elements_per_rank"] = rank_counts(elems);
    jb["nodes_per_rank"] = rank_counts(nodes);
    if (c.dynamic()) {
      // Settings of other models that the body carries (switching `model:` would use them).
      const std::string note = io::unused_settings_note(b);
      if (!note.empty()) print0(ctx.comm(), "  %s\n", note.c_str());
      io::Json unused = io::Json::array();
      for (const std::string &key : io::unused_settings(b)) unused.push_back(key);
      jb["unused_settings"] = unused;
    }
    if (c.dynamic() && dynamics::simulated_model(b.model) == dynamics::BodyModel::Ffrf) {
      // The reduced size follows from the case alone: 6 static modes per interface after the
      // frame, plus the fixed-interface modes (flexopt modes --body shows the basis itself).
      const int statics = 6 * std::max(0, static_cast<int>(b.interfaces.size()) - 1);
      print0(
          ctx.comm(),
          "  ffrf: %d elastic coordinates (%d static modes + %d fixed-interface modes), frame %s "
          "at interface '%s', geometric stiffening %s, Rayleigh damping [%g, %g]\n",
          statics + b.reduction.modes, statics, b.reduction.modes,
          dynamics::frame_name(b.reduction.frame),
          b.interfaces.empty() ? "(none)" : b.interfaces.front().c_str(),
          b.reduction.geometric_stiffening ? "on" : "off", b.rayleigh[0], b.rayleigh[1]);
      jb["elastic_coordinates"] = statics + b.reduction.modes;
      jb["static_modes"] = statics;
      jb["fixed_modes"] = b.reduction.modes;
      jb["frame"] = dynamics::frame_name(b.reduction.frame);
    }
    check_sensor_points(ctx, c, b, m);
    bodies.push_back(jb);
    total_dofs += 3LL * m.global_nodes;
    total_elements += m.global_elements;
  }
  s["dofs"] = total_dofs;
  s["elements"] = total_elements;
  s["bodies"] = bodies;
  write_summary(ctx, dir, s, t0);
  return 0;
}

namespace {

/// One static solve of `c` (a case, or one load case's case): prints the solve, writes
/// dir/NAME.xdmf (displacement, von Mises, owner rank) and the solve's figures into s; returns
/// the .xdmf path. Collective.
std::string solve_static(const Context &ctx, const io::Case &c, const std::string &design_file,
                         const std::string &dir, const std::string &name, io::Json &s) {
  const double t_setup = wall_time();
  // With --design FILE: the responses of the case's topology problem at that design; the solve
  // and the output below are of its last state solve (the stiffness of that design).
  std::unique_ptr<optimize::TopologyProblem> topology;
  std::unique_ptr<fem::StaticProblem> plain;
  if (design_file.empty())
    plain = fem::StaticProblem::create(ctx.comm(), io::static_settings(c));
  else
    topology = optimize::TopologyProblem::create(ctx.comm(), io::topology_settings(c));
  fem::StaticProblem *problem = plain ? plain.get() : &topology->static_problem();
  const auto &m = problem->mesh();
  print0(ctx.comm(),
         "static: %lld DOFs on %d rank(s), K and f assembled in %.2f s (set-up %.2f s)\n",
         static_cast<long long>(problem->global_dofs()), ctx.size(), problem->timings().assemble,
         wall_time() - t_setup);
  const double t_solve = wall_time();
  if (plain) {
    problem->solve();
  } else {
    Vec x = topology->create_design_vector();
    detail::load_design(ctx.comm(), c, *topology, design_file, x);
    print0(ctx.comm(), "design: the densities of %s\n", design_file.c_str());
    optimize::Evaluation ev;
    topology->evaluate(x, false, ev);
    io::Json responses = io::Json::object();
    const auto &names = topology->response_names();
    for (std::size_t i = 0; i < names.size(); ++i) {
      const std::string key = i == 0 ? "objective" : "constraint" + std::to_string(i - 1);
      responses[key] = ev.value(i);
      print0(ctx.comm(), "response %-12s %-28s %.10g\n", key.c_str(), names[i].c_str(),
             ev.value(i));
    }
    s["responses"] = responses;
    FX_PETSC(VecDestroy(&x));
  }
  const double solve_s = wall_time() - t_solve;
  const double compliance = problem->compliance(), umax = problem->max_displacement();
  print0(ctx.comm(),
         "static: solved in %.2f s (preconditioner %.2f s, %d iterations %.2f s); compliance %.10g "
         "J, max |u| %.6g m\n",
         solve_s, problem->timings().setup, problem->iterations(), problem->timings().solve,
         compliance, umax);

  s["element_type"] = fem::element_name(m.type);
  s["dofs"] = static_cast<long long>(problem->global_dofs());
  s["elements"] = static_cast<long long>(m.global_elements);
  s["solver_iterations"] = problem->iterations();
  s["solve_s"] = solve_s;
  const auto &tm = problem->timings();
  io::Json timings = io::Json::object();
  timings["mesh_s"] = tm.mesh;
  timings["assemble_s"] = tm.assemble;
  timings["pc_setup_s"] = tm.setup;
  timings["ksp_solve_s"] = tm.solve;
  s["timings"] = timings;
  s["compliance"] = compliance;
  s["max_displacement"] = umax;
  io::Json sensors = io::Json::object();
  for (const auto &sensor : c.scene.sensors) {
    auto u = fem::probe_vector(m, problem->displacement(), sensor.point,
                               sensor.where.str() + ": sensor '" + sensor.name + "'");
    if (sensor.quantity == dynamics::SensorQuantity::Position)
      for (int k = 0; k < 3; ++k)
        u[static_cast<std::size_t>(k)] += sensor.point[static_cast<std::size_t>(k)];
    sensors[sensor.name]["quantity"] = dynamics::quantity_name(sensor.quantity);
    sensors[sensor.name]["point"] = std::vector<double>(sensor.point.begin(), sensor.point.end());
    sensors[sensor.name]["value"] = std::vector<double>(u.begin(), u.end());
    print0(ctx.comm(), "sensor %s (%s at %g %g %g): [%.10g, %.10g, %.10g]\n", sensor.name.c_str(),
           dynamics::quantity_name(sensor.quantity), sensor.point[0], sensor.point[1],
           sensor.point[2], u[0], u[1], u[2]);
  }
  s["sensors"] = sensors;

  io::XdmfWriter writer(mesh::grid_layout(m), dir, name);
  writer.begin_step(0.0);
  const PetscScalar *u;
  FX_PETSC(VecGetArrayRead(problem->displacement(), &u));
  writer.node_vector("displacement", u);
  FX_PETSC(VecRestoreArrayRead(problem->displacement(), &u));
  const auto vm = fem::element_von_mises(m, problem->material(), problem->modulus_factor(),
                                         problem->displacement());
  writer.cell_scalar("von_mises", vm.data());
  const auto owner = owner_field(m);
  writer.cell_scalar("rank", owner.data());
  const std::string xdmf = writer.close();
  s["output"] = xdmf;
  return xdmf;
}

} // namespace

int run_static(const Context &ctx, const Options &o, const io::Case &c, double t0) {
  if (c.dynamic())
    throw Error(
        c.file + ": analysis '" + c.analysis_name() +
            "' is not available yet in this version of flexopt (static only; `flexopt modes` "
            "works on any single body)",
        true);
  const std::string dir = output_directory(ctx, o);
  io::Json s = base_summary(ctx, o, c);
  s["analysis"] = "static";
  std::string outputs;
  if (c.load_cases.empty()) {
    outputs = solve_static(ctx, c, o.design, dir, "static", s);
  } else {
    // Every load case, one after another on all ranks: static.NAME.xdmf, its figures under
    // summary.json's load_cases.NAME.
    s["load_cases"] = each_condition(
        ctx, c, [&](const io::Case &one, const std::string &name, io::Json &figures) {
          outputs += (outputs.empty() ? "" : ", ") +
                     solve_static(ctx, one, o.design, dir, "static." + name, figures);
        });
  }
  write_summary(ctx, dir, s, t0);
  print0(ctx.comm(), "wrote %s (open in ParaView) and %s\n", outputs.c_str(),
         (fs::path(dir) / "summary.json").c_str());
  return 0;
}

/// `modes --body NAME`: the Craig-Bampton basis of one body, and how well the reduced model
/// reproduces the frequencies of the full body clamped at its first interface.
int run_reduction(const Context &ctx, const Options &o, const io::Case &c, double t0) {
  const dynamics::BodyDescription *body = nullptr;
  for (const auto &b : c.scene.bodies)
    if (b.name == o.body) body = &b;
  if (!body) {
    std::string names;
    for (const auto &b : c.scene.bodies) names += (names.empty() ? "" : ", ") + b.name;
    throw Error(c.file + ": modes --body: no body named '" + o.body + "' (bodies: " + names + ")",
                true);
  }
  if (body->interfaces.empty())
    throw Error(body->where.str() + ": body '" + body->name +
                    "' lists no interfaces; a reduction basis is clamped at the first one",
                true);
  const std::string dir = output_directory(ctx, o);
  mesh::DistributedMesh m = mesh::load_body_mesh(ctx.comm(), body->mesh);
  const fem::IsotropicMaterial mat = body->material;
  Mat K, M;
  fem::assemble_stiffness_and_mass(m, mat, K, M);
  const double t_red = wall_time();
  reduce::CraigBamptonBasis cb;
  reduce::craig_bampton(m, K, M, body->interfaces, o.count, cb);
  const double reduction_s = wall_time() - t_red;
  // The reduced model's frequencies (Rayleigh-Ritz in the span of the basis) against the full
  // body clamped at the frame interface only.
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> red(cb.K, cb.M);
  reduce::ModalResult full;
  const auto frame = fem::surface_dofs(m, body->interfaces.front(), {true, true, true},
                                       body->where.str() + ": interfaces");
  const int nfull = std::min<int>(o.count, static_cast<int>(cb.K.rows()));
  reduce::solve_modes(K, M, frame, nfull, kModalShift, full);
  if (body->reduction.frame == reduce::FrameCondition::Chord)
    print0(ctx.comm(),
           "note: body %s uses reduction.frame: chord; this command shows the basis and "
           "frequencies with the frame clamped at '%s' (the chord frame adds a rigid rotation to "
           "each vector, docs/theory.md section 7.1)\n",
           body->name.c_str(), body->interfaces.front().c_str());
  print0(ctx.comm(),
         "reduction of body %s: %lld DOFs -> %d coordinates (%d static modes for %zu interface(s) "
         "after the frame '%s', %d fixed-interface modes) in %.2f s\n",
         body->name.c_str(), static_cast<long long>(3 * m.global_nodes),
         static_cast<int>(cb.K.rows()), cb.static_modes, body->interfaces.size() - 1,
         body->interfaces.front().c_str(), cb.fixed_modes, reduction_s);
  for (std::size_t k = 0; k < cb.centroids.size(); ++k)
    print0(ctx.comm(), "  interface %-12s centroid (%.6g, %.6g, %.6g)\n",
           body->interfaces[k].c_str(), cb.centroids[k].x(), cb.centroids[k].y(),
           cb.centroids[k].z());
  std::vector<double> fixed_hz, reduced_hz, full_hz;
  for (double l : cb.fixed_eigenvalues) fixed_hz.push_back(reduce::frequency_hz(l));
  for (Eigen::Index k = 0; k < red.eigenvalues().size(); ++k)
    reduced_hz.push_back(reduce::frequency_hz(red.eigenvalues()(k)));
  for (int k = 0; k < nfull; ++k)
    full_hz.push_back(reduce::frequency_hz(full.eigenvalues[static_cast<std::size_t>(k)]));
  print0(ctx.comm(), "  %4s %18s %18s %18s %10s\n", "k", "fixed-interface Hz", "reduced model Hz",
         "full (frame clamped)", "difference");
  for (int k = 0; k < nfull; ++k)
    print0(ctx.comm(), "  %4d %18.6f %18.6f %18.6f %9.3f%%\n", k + 1,
           k < static_cast<int>(fixed_hz.size()) ? fixed_hz[static_cast<std::size_t>(k)] : 0.0,
           reduced_hz[static_cast<std::size_t>(k)], full_hz[static_cast<std::size_t>(k)],
           100 * (reduced_hz[static_cast<std::size_t>(k)] - full_hz[static_cast<std::size_t>(k)]) /
               full_hz[static_cast<std::size_t>(k)]);
  io::XdmfWriter writer(mesh::grid_layout(m), dir, "reduction");
  for (std::size_t k = 0; k < cb.vectors.size(); ++k) {
    writer.begin_step(static_cast<double>(k + 1));
    const PetscScalar *v;
    FX_PETSC(VecGetArrayRead(cb.vectors[k], &v));
    writer.node_vector("basis_vector", v);
    FX_PETSC(VecRestoreArrayRead(cb.vectors[k], &v));
  }
  const std::string xdmf = writer.close();
  FX_PETSC(MatDestroy(&K));
  FX_PETSC(MatDestroy(&M));
  io::Json s = base_summary(ctx, o, c);
  io::Json r = io::Json::object();
  r["body"] = body->name;
  r["dofs"] = static_cast<long long>(3 * m.global_nodes);
  r["static_modes"] = cb.static_modes;
  r["fixed_modes"] = cb.fixed_modes;
  r["fixed_frequencies_hz"] = fixed_hz;
  r["reduced_frequencies_hz"] = reduced_hz;
  r["full_frequencies_hz"] = full_hz;
  r["reduction_s"] = reduction_s;
  s["reduction"] = r;
  s["output"] = xdmf;
  write_summary(ctx, dir, s, t0);
  print0(ctx.comm(),
         "wrote %s (basis vectors as steps: static modes, then fixed-interface modes) "
         "and %s\n",
         xdmf.c_str(), (fs::path(dir) / "summary.json").c_str());
  return 0;
}

int run_modes(const Context &ctx, const Options &o, const io::Case &c, double t0) {
  if (!o.body.empty()) return run_reduction(ctx, o, c, t0);
  if (c.scene.bodies.size() != 1)
    throw Error(c.file + ": modes: the case has " + std::to_string(c.scene.bodies.size()) +
                    " bodies; modal analysis takes a single-body case",
                true);
  const std::string dir = output_directory(ctx, o);
  const dynamics::BodyDescription &body = c.scene.bodies.front();
  const double t_setup = wall_time();
  mesh::DistributedMesh m = mesh::load_body_mesh(ctx.comm(), body.mesh);
  const fem::IsotropicMaterial mat = body.material;
  std::vector<PetscInt> fixed;
  if (!o.free) fixed = fem::support_dofs(m, c.loads.supports);
  PetscInt nfix = static_cast<PetscInt>(fixed.size()), total_fixed = 0;
  MPI_Allreduce(&nfix, &total_fixed, 1, MPIU_INT, MPI_SUM, ctx.comm());
  const PetscInt dofs = 3 * m.global_nodes;
  if (o.count > dofs - total_fixed)
    throw Error("modes: --count " + std::to_string(o.count) + " exceeds the " +
                    std::to_string(dofs - total_fixed) + " free DOFs of the body",
                true);
  Mat K, M;
  fem::assemble_stiffness_and_mass(m, mat, K, M);
  print0(ctx.comm(),
         "modes: %lld DOFs (%lld fixed) on %d rank(s), %s; K and M assembled (set-up %.2f s)\n",
         static_cast<long long>(dofs), static_cast<long long>(total_fixed), ctx.size(),
         total_fixed ? "supported" : "free-free", wall_time() - t_setup);
  const double t_solve = wall_time();
  reduce::ModalResult r;
  reduce::solve_modes(K, M, fixed, o.count, kModalShift, r);
  const double solve_s = wall_time() - t_solve;
  print0(ctx.comm(), "modes: solved in %.2f s (%d iterations)\n", solve_s, r.iterations);

  std::vector<double> freq;
  io::XdmfWriter writer(mesh::grid_layout(m), dir, "modes");
  for (std::size_t k = 0; k < r.eigenvalues.size(); ++k) {
    freq.push_back(reduce::frequency_hz(r.eigenvalues[k]));
    print0(ctx.comm(), "  mode %2zu: %14.6f Hz\n", k + 1, freq.back());
    // Shapes are written scaled to a unit largest nodal displacement, sign fixed so that the
    // largest component is positive: comparable across runs and ranks.
    PetscReal vmax, vmin;
    PetscInt imax, imin;
    FX_PETSC(VecMax(r.modes[k], &imax, &vmax));
    FX_PETSC(VecMin(r.modes[k], &imin, &vmin));
    const double scale = (std::abs(vmax) >= std::abs(vmin)) ? vmax : vmin;
    if (scale != 0.0) FX_PETSC(VecScale(r.modes[k], 1.0 / scale));
    writer.begin_step(static_cast<double>(k + 1));
    const PetscScalar *v;
    FX_PETSC(VecGetArrayRead(r.modes[k], &v));
    writer.node_vector("mode_shape", v);
    FX_PETSC(VecRestoreArrayRead(r.modes[k], &v));
  }
  const std::string xdmf = writer.close();
  FX_PETSC(MatDestroy(&K));
  FX_PETSC(MatDestroy(&M));

  io::Json s = base_summary(ctx, o, c);
  s["element_type"] = fem::element_name(m.type);
  s["dofs"] = static_cast<long long>(dofs);
  s["elements"] = static_cast<long long>(m.global_elements);
  s["supported"] = total_fixed > 0;
  s["solver_iterations"] = r.iterations;
  s["solve_s"] = solve_s;
  s["eigenvalues"] = r.eigenvalues;
  s["frequencies_hz"] = freq;
  s["output"] = xdmf;
  write_summary(ctx, dir, s, t0);
  print0(ctx.comm(), "wrote %s (one mode per time step) and %s\n", xdmf.c_str(),
         (fs::path(dir) / "summary.json").c_str());
  return 0;
}

int run_optimize(const Context &ctx, const Options &o, const io::Case &c, double t0) {
  if (c.design.empty())
    throw Error(c.file + ": optimize needs design:, objective: (and constraints:) sections", true);
  if (c.esl) return run_esl(ctx, o, c, t0);
  const std::string dir = output_directory(ctx, o);
  io::Case run_case = c;
  if (o.max_iterations > 0) run_case.optimizer.max_iterations = o.max_iterations;
  auto problem = detail::create_design_problem(ctx.comm(), run_case, true, dir, o.scenario_groups);
  const auto r =
      optimize::run_optimization(ctx.comm(), *problem, run_case.optimizer, dir, o.restart);
  io::Json s = base_summary(ctx, o, c);
  s["dofs"] = r.dofs;
  s["elements"] = r.elements;
  s["design_variables"] = r.design_variables;
  s["iterations"] = r.iterations;
  s["objective"] = r.objective;
  io::Json cons = io::Json::array();
  for (const auto &row : r.constraints) cons.push_back(io::Json(row));
  s["constraints"] = cons;
  s["constraint_bounds"] = run_case.optimizer.bounds; // each constraint's max, in the same order
  s["max_change"] = r.max_change;
  io::Json split = io::Json::object();
  for (std::size_t p = 0; p < r.split_names.size(); ++p) {
    std::vector<double> column;
    for (const auto &row : r.seconds_split) column.push_back(row[p]);
    split[r.split_names[p]] = column;
  }
  s["seconds_split"] = split; // per part, per iteration
  io::Json about = io::Json::object();
  problem->describe(about);
  s["problem"] = about;
  s["volume_fraction"] = r.volume_fraction;
  if (!r.body_volume_fractions.empty()) { // several design bodies: each one's
    io::Json per = io::Json::object();
    for (std::size_t b = 0; b < r.body_volume_fractions.size(); ++b)
      per[r.design_bodies[b]] = r.body_volume_fractions[b];
    s["body_volume_fractions"] = per;
  }
  s["converged"] = r.converged;
  s["restarted"] = o.restart;
  s["stop_reason"] = r.stop_reason;
  if (!r.warnings.empty()) {
    io::Json w = io::Json::array();
    for (const std::string &line : r.warnings) w.push_back(line);
    s["warnings"] = w;
  }
  s["output"] = r.output;
  io::Json design_output = io::Json::object();
  design_output["every"] = r.output_stride;
  design_output["frames"] = r.output_frames;
  design_output["estimated_bytes"] = r.output_estimated_bytes;
  std::error_code h5_error, xdmf_error;
  const auto h5_bytes = fs::file_size(fs::path(dir) / "design.h5", h5_error);
  const auto xdmf_bytes = fs::file_size(r.output, xdmf_error);
  if (!h5_error && !xdmf_error) design_output["bytes"] = static_cast<double>(h5_bytes + xdmf_bytes);
  s["design_output"] = design_output;
  io::Json stages = io::Json::array();
  for (const auto &[first, beta] : r.beta_stages) {
    io::Json st = io::Json::object();
    st["first_iteration"] = first;
    if (beta.size() == 1) {
      st["beta"] = beta.front();
    } else { // several design bodies: each one's
      io::Json per = io::Json::object();
      for (std::size_t b = 0; b < beta.size(); ++b) per[r.design_bodies[b]] = beta[b];
      st["beta"] = per;
    }
    stages.push_back(st);
  }
  s["beta_stages"] = stages;
  s["history"] = (fs::path(dir) / "history.csv").string();
  if (auto *dynamic = dynamic_cast<adjoint::DynamicProblem *>(problem.get()))
    write_design_motions(ctx, run_case, *dynamic, dir, s);
  else if (!run_case.scenarios.empty())
    write_scenario_motions(ctx, run_case, dir, s);
  write_summary(ctx, dir, s, t0);
  print0(ctx.comm(),
         "wrote %s (densities every %d iteration(s) and the final design: threshold "
         "physical_density at 0.5 in ParaView), %s, %s\n",
         r.output.c_str(), r.output_stride, (fs::path(dir) / "history.csv").c_str(),
         (fs::path(dir) / "summary.json").c_str());
  after_run(ctx, o, c, dir);
  return 0;
}

/// `flexopt plan CASE`: the choice per body with its reasons, numbers and predicted cost
/// (docs/theory.md section 12); nothing is integrated but the rigid pre-run.
int run_plan(const Context &ctx, const Options &o, io::Case c, double t0) {
  if (!c.dynamic())
    throw Error(c.file + ": flexopt plan chooses the models of a dynamic analysis (this case is " +
                    c.analysis_name() + ")",
                true);
  const std::string dir = output_directory(ctx, o);
  print0(ctx.comm(), "case %s (%s), plan, %d rank(s)%s\n", c.name.c_str(), c.file.c_str(),
         ctx.size(), o.all_auto ? ", every body estimated as model: auto (--auto)" : "");
  if (o.all_auto)
    for (dynamics::BodyDescription &b : c.scene.bodies) b.model = dynamics::BodyModel::Auto;
  const plan::Plan p = plan::make_plan(ctx.comm(), io::plan_settings(c));
  plan::print_plan(ctx.comm(), p);
  io::Json s = base_summary(ctx, o, c);
  s["plan"] = plan::plan_json(p);
  s["accuracy"] = p.accuracy;
  s["prerun_s"] = p.prerun_s;
  s["steps"] = p.steps;
  s["plan_s"] = p.seconds;
  write_summary(ctx, dir, s, t0);
  print0(ctx.comm(), "wrote %s/summary.json\n", dir.c_str());
  return 0;
}

} // namespace

int run(const Context &ctx, const Options &given) {
  const double t0 = wall_time();
  Options o = given;
  if (o.command == "report") return run_report(ctx, o); // OUT, not a case
  io::Case c = io::load_case(o.case_dir);
  const std::string solver =
      o.command == "check-gradient" ? check_gradient_solver_options(ctx, c) : c.solver;
  if (!solver.empty()) insert_default_petsc_options(solver, c.file + ": solver");
  if (o.command == "plan") return run_plan(ctx, o, c, t0);
  // `model: auto` bodies of a dynamic case take the plan's models (docs/theory.md section 12).
  if (c.dynamic() && o.command != "info" &&
      std::any_of(c.scene.bodies.begin(), c.scene.bodies.end(),
                  [](const dynamics::BodyDescription &b) {
                    return b.model == dynamics::BodyModel::Auto;
                  })) {
    const plan::Plan p = plan::make_plan(ctx.comm(), io::plan_settings(c));
    plan::print_plan(ctx.comm(), p);
    o.plan = plan::plan_json(p);
    plan::apply_plan(c.scene, p);
    // Every scenario takes the models planned for the case's own scene.
    for (io::Scenario &sc : c.scenarios) plan::apply_plan(sc.scene, p);
  }
  const bool dynamic_simulate = o.command == "simulate" && c.dynamic() && !c.design.empty();
  if (!o.design.empty() &&
      !((o.command == "simulate" || o.command == "check-gradient") && !c.design.empty()))
    throw Error("--design applies to `flexopt simulate` and `flexopt check-gradient` of a case "
                "with a design: section; " +
                    c.file + " is " + c.analysis_name() +
                    (!c.design.empty() ? "" : " without design:"),
                true);
  if (o.gradient && !dynamic_simulate)
    throw Error("--gradient applies to `flexopt simulate` of a dynamic case with a design: "
                "section; " +
                    c.file + " is " + c.analysis_name() +
                    (!c.design.empty() ? "" : " without design:"),
                true);
  if (o.command == "info") return run_info(ctx, o, c, t0);
  if (o.command == "simulate")
    return c.dynamic() ? run_dynamic(ctx, o, c, t0) : run_static(ctx, o, c, t0);
  if (o.command == "modes") return run_modes(ctx, o, c, t0);
  if (o.command == "check-gradient") return run_check_gradient(ctx, o, c, t0);
  if (o.command == "optimize") return run_optimize(ctx, o, c, t0);
  throw Error("unknown command '" + o.command + "'", true);
}

} // namespace flexopt::app
