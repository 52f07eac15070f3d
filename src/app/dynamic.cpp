// `flexopt simulate` for `analysis: dynamic`: a mechanism of rigid and FFRF bodies integrated
// with generalized-alpha; motion.xdmf (every body's mesh moving and, for flexible bodies,
// deforming), summary.json (sensors, energy, constraint violation, Newton statistics).
#include "app_common.hpp"
#include "flexopt/bodies/ffrf_body.hpp"
#include "flexopt/bodies/rigid_body.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"
#include "flexopt/dynamics/scene.hpp"
#include "flexopt/io/motion_writer.hpp"

#include <cmath>
#include <sstream>

namespace flexopt::app {

namespace {

/// Largest residual, relative to the scene's size, that a row left out as redundant may reach
/// before the run stops (structurally redundant rows stay at round-off, ~1e-15).
constexpr double kRedundantDriftTolerance = 1e-8;

/// Current world coordinates of the owned nodes of body b and, for a flexible body, their
/// elastic displacement Psi zeta (frame axes) into `elastic`.
std::vector<double> body_positions(const dynamics::Scene &scene, std::size_t b,
                                   const dynamics::Vector &q, std::vector<double> &elastic) {
  const mesh::DistributedMesh &m = scene.meshes[b];
  const dynamics::Mechanism &mech = scene.mechanism;
  const int o = mech.offset(static_cast<int>(b)), ne = mech.size(static_cast<int>(b)) - 7;
  const bodies::Vec3 r = q.segment<3>(o), origin = mech.bodies[b]->origin();
  const bodies::Mat3 A = bodies::rotation(q.segment<4>(o + 3));
  const auto nodes = static_cast<std::size_t>(m.owned_nodes);
  std::vector<double> x(3 * nodes);
  elastic.assign(ne > 0 ? 3 * nodes : 0, 0.0);
  if (ne > 0)
    Eigen::Map<Eigen::VectorXd>(elastic.data(), static_cast<Eigen::Index>(3 * nodes)) =
        scene.owned_modes[b] * q.segment(o + 7, ne);
  for (std::size_t i = 0; i < nodes; ++i) {
    bodies::Vec3 X(m.coordinates[3 * i], m.coordinates[3 * i + 1], m.coordinates[3 * i + 2]);
    X -= origin;
    if (ne > 0) X += bodies::Vec3(elastic[3 * i], elastic[3 * i + 1], elastic[3 * i + 2]);
    const bodies::Vec3 p = r + A * X;
    for (std::size_t k = 0; k < 3; ++k) x[3 * i + k] = p(static_cast<Eigen::Index>(k));
  }
  return x;
}

io::Json vec3_json(const bodies::Vec3 &v) {
  return io::Json(std::vector<double>{v.x(), v.y(), v.z()});
}

} // namespace

int run_dynamic(const Context &ctx, const Options &o, const io::Case &c, double t0) {
  const std::string dir = detail::output_directory(ctx, o);
  io::Json s = detail::base_summary(ctx, o, c);
  s["analysis"] = "dynamic";
  print0(ctx.comm(), "case %s (%s), analysis: dynamic, %d rank(s)\n", c.name.c_str(),
         c.file.c_str(), ctx.size());
  dynamics::Scene scene = dynamics::build_scene(ctx.comm(), c);
  const dynamics::Mechanism &mech = scene.mechanism;
  print0(ctx.comm(), "mechanism: %zu bodies, %d coordinates, %d constraint rows enforced of %d\n",
         mech.bodies.size(), mech.coordinates(), mech.constraints(), mech.all_rows());
  io::Json redundant = io::Json::array();
  for (const auto &r : scene.redundant_rows) {
    print0(ctx.comm(),
           "mechanism: redundant constraint %s is implied by the others and is not enforced "
           "(its residual is monitored)\n",
           r.c_str());
    redundant.push_back(r);
  }
  s["redundant_constraints"] = redundant;

  const auto par = dynamics::AlphaParameters::from_rho_inf(c.time.rho_inf);
  dynamics::NewtonSettings newton;
  newton.reuse_contraction = c.time.newton_reuse;
  const dynamics::GeneralizedAlpha ga(mech, par, newton);
  dynamics::State state = ga.initial_state(scene.q0, scene.v0, 0.0);
  const double h = c.time.step;
  const long long steps = std::llround(c.time.end / h);
  print0(ctx.comm(),
         "integrate: generalized-alpha rho_inf = %g (alpha_m %.4f, alpha_f %.4f, gamma %.4f, beta "
         "%.4f), %lld steps of %g s to t = %g s; Newton matrix kept while the contraction is <= "
         "%g\n",
         par.rho_inf, par.alpha_m, par.alpha_f, par.gamma, par.beta, steps, h,
         static_cast<double>(steps) * h, newton.reuse_contraction);

  std::vector<io::MotionBody> mb;
  for (std::size_t b = 0; b < mech.bodies.size(); ++b)
    mb.push_back({mech.bodies[b]->name(), mesh::grid_layout(scene.meshes[b])});
  io::MotionWriter writer(mb, dir, "motion");

  std::vector<double> out_t, energy;
  std::vector<std::vector<bodies::Vec3>> sensor_values(scene.sensors.size());
  double max_violation = 0;
  dynamics::Vector all;
  // Largest residual of every row (the violation monitor) and of the rows left out as
  // redundant, with that row.
  struct Residuals {
    double unenforced = 0;
    int row = -1;
  };
  auto monitor = [&](const dynamics::State &st) {
    mech.all_constraint_values(st.q, st.t, all);
    Residuals out;
    for (int r = 0; r < all.size(); ++r) {
      const double v = std::abs(all(r));
      max_violation = std::max(max_violation, v);
      if (!mech.enforced(r) && v >= out.unenforced) out.unenforced = v, out.row = r;
    }
    return out;
  };
  auto record = [&](const dynamics::State &st) {
    out_t.push_back(st.t);
    energy.push_back(mech.energy(st.q, st.v));
    for (std::size_t k = 0; k < scene.sensors.size(); ++k)
      sensor_values[k].push_back(dynamics::sensor_value(scene, scene.sensors[k], st.q));
    writer.begin_step(st.t);
    std::vector<double> elastic;
    for (std::size_t b = 0; b < mech.bodies.size(); ++b) {
      const auto x = body_positions(scene, b, st.q, elastic);
      writer.positions(b, x.data());
      if (mech.size(static_cast<int>(b)) > 7)
        writer.node_vector(b, "elastic_displacement", elastic.data());
    }
  };
  monitor(state);
  record(state);

  long long newton_total = 0, factorizations_total = 0;
  int newton_max = 0, halvings_max = 0;
  const double t_start = wall_time();
  double last_print = t_start;
  dynamics::State next;
  for (long long n = 0; n < steps; ++n) {
    dynamics::StepInfo info;
    if (!ga.advance(state, h, next, info)) {
      std::ostringstream msg;
      msg << "integrate: Newton did not converge in step " << n + 1 << " (t = " << state.t
          << " s -> " << state.t + h << " s) after "
          << (1 << dynamics::NewtonSettings{}.max_halvings)
          << "-fold step halving; increments of the last attempt:";
      for (double v : info.increment) msg << ' ' << v;
      msg << "; constraint residuals:";
      for (double v : info.violation) msg << ' ' << v;
      msg << ". Reduce time.step or check the scene (a singular configuration, a driver "
             "demanding impossible motion).";
      throw Error(msg.str(), true); // replicated computation: every rank fails here
    }
    next.t = static_cast<double>(n + 1) * h; // no drift of t over many steps
    state = next;
    // Rows left out as redundant must stay satisfied: if one does not, it was only dependent
    // in the initial configuration (a singular position such as a dead point), not
    // structurally, and the mechanism is not what the case describes.
    const Residuals res = monitor(state);
    if (res.unenforced > kRedundantDriftTolerance * scene.length_scale)
      throw Error("integrate: at t = " + std::to_string(state.t) + " s (step " +
                      std::to_string(n + 1) + ") the constraint " + mech.describe_row(res.row) +
                      ", left out as redundant at t = 0, is violated by " +
                      std::to_string(res.unenforced) +
                      ": the initial placement is a singular configuration of the mechanism (a "
                      "dead point or aligned links), not a structural redundancy. Place the "
                      "bodies away from it.",
                  true);
    newton_total += info.iterations;
    factorizations_total += info.factorizations;
    newton_max = std::max(newton_max, info.iterations);
    halvings_max = std::max(halvings_max, info.halvings);
    if ((n + 1) % c.output_every == 0 || n + 1 == steps) record(state);
    const double now = wall_time();
    if (now - last_print > 2.0 || n + 1 == steps) {
      const double rate = static_cast<double>(n + 1) / std::max(now - t_start, 1e-9);
      print0(ctx.comm(),
             "  t = %-10.6g step %lld/%lld  Newton %.2f/step  %.0f steps/s  ETA %.1f s\n", state.t,
             n + 1, steps, static_cast<double>(newton_total) / static_cast<double>(n + 1), rate,
             static_cast<double>(steps - n - 1) / rate);
      last_print = now;
    }
  }
  const double t_int = wall_time() - t_start;
  const std::string xdmf = writer.close();

  s["coordinates"] = mech.coordinates();
  s["constraint_rows"] = mech.constraints();
  s["steps"] = steps;
  s["time_step"] = h;
  s["t_end"] = static_cast<double>(steps) * h;
  s["rho_inf"] = par.rho_inf;
  s["output_times"] = io::Json(out_t);
  s["energy"] = io::Json(energy);
  s["constraint_violation_max"] = max_violation;
  s["newton_iterations_total"] = newton_total;
  s["newton_iterations_max"] = newton_max;
  s["newton_factorizations_total"] = factorizations_total;
  s["newton_reuse"] = newton.reuse_contraction;
  s["step_halvings_max"] = halvings_max;
  s["integration_s"] = t_int;
  s["steps_per_second"] = static_cast<double>(steps) / std::max(t_int, 1e-9);
  io::Json sensors = io::Json::object();
  for (std::size_t k = 0; k < scene.sensors.size(); ++k) {
    io::Json one = io::Json::object();
    one["quantity"] = scene.sensors[k].quantity;
    one["t"] = io::Json(out_t);
    io::Json vals = io::Json::array();
    for (const auto &v : sensor_values[k]) vals.push_back(vec3_json(v));
    one["value"] = vals;
    sensors[scene.sensors[k].name] = one;
  }
  s["sensors"] = sensors;
  io::Json bl = io::Json::array();
  for (std::size_t k = 0; k < mech.bodies.size(); ++k) {
    const auto &b = mech.bodies[k];
    io::Json j = io::Json::object();
    j["name"] = b->name();
    j["model"] = b->model();
    j["mass"] = b->mass();
    if (const auto *rigid = dynamic_cast<const bodies::RigidBody *>(b.get())) {
      j["center"] = vec3_json(rigid->center());
      j["inertia"] =
          io::Json(std::vector<double>(rigid->inertia().data(), rigid->inertia().data() + 9));
    } else {
      j["frame_origin"] = vec3_json(b->origin());
      j["elastic_coordinates"] = b->elastic_coordinates();
      j["dofs"] = 3LL * scene.meshes[k].global_nodes;
      j["elements"] = static_cast<long long>(scene.meshes[k].global_elements);
      j["reduction_s"] = scene.reduction_seconds[k];
    }
    bl.push_back(j);
  }
  s["bodies"] = bl;
  print0(ctx.comm(),
         "integrate: %lld steps in %.3f s (%.0f steps/s), %lld Newton iterations (max %d per "
         "step) on %lld factorized matrices, max constraint violation %.3e, energy %.9g -> "
         "%.9g\n",
         steps, t_int, static_cast<double>(steps) / std::max(t_int, 1e-9), newton_total, newton_max,
         factorizations_total, max_violation, energy.front(), energy.back());
  detail::write_summary(ctx, dir, s, t0);
  print0(ctx.comm(), "wrote %s (open in ParaView and press play) and %s/summary.json\n",
         xdmf.c_str(), dir.c_str());
  return 0;
}

} // namespace flexopt::app
