/// \file load_case: case.yaml (docs/case-format.md) read section by section (the scene in
/// case_scene.cpp, the optimization in case_optimization.cpp; the loads, time and output here),
/// a body's model-dependent settings, and the translations into the modules' settings.
#include "flexopt/io/case.hpp"

#include "case_reader.hpp"
#include "case_sections.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/expression.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>
#include <yaml-cpp/yaml.h>

namespace fs = std::filesystem;

namespace flexopt::io {

const MaterialSpec &Case::material(const std::string &n) const {
  for (const auto &m : materials)
    if (m.name == n) return m;
  throw Error("no material '" + n + "' in " + file, true);
}

const std::vector<ModelSetting> &model_settings() {
  using dynamics::BodyModel;
  static const std::vector<ModelSetting> settings = {
      {"reduction.modes", {BodyModel::Ffrf}},
      {"reduction.geometric_stiffening", {BodyModel::Ffrf}},
      // An ACF body measures its elastic displacement in that frame (docs/theory.md 8.4).
      {"reduction.frame", {BodyModel::Ffrf, BodyModel::Acf}},
      {"damping", {BodyModel::Ffrf, BodyModel::Acf}},
      {"initial.elastic_displacement", {BodyModel::Ffrf, BodyModel::Acf}},
      {"initial.elastic_velocity", {BodyModel::Ffrf, BodyModel::Acf}},
  };
  return settings;
}

std::vector<std::string> settings_used_by(dynamics::BodyModel model) {
  const dynamics::BodyModel simulated = dynamics::simulated_model(model);
  std::vector<std::string> keys;
  for (const ModelSetting &s : model_settings())
    if (std::find(s.models.begin(), s.models.end(), simulated) != s.models.end())
      keys.push_back(s.key);
  return keys;
}

std::vector<std::string> unused_settings(const dynamics::BodyDescription &body) {
  const std::vector<std::string> used = settings_used_by(body.model);
  std::vector<std::string> unused;
  for (const ModelSetting &s : model_settings())
    if (std::find(body.settings.begin(), body.settings.end(), s.key) != body.settings.end() &&
        std::find(used.begin(), used.end(), s.key) == used.end())
      unused.push_back(s.key);
  return unused;
}

std::string unused_settings_note(const dynamics::BodyDescription &body) {
  std::string list;
  for (const std::string &key : unused_settings(body)) {
    std::string models;
    for (const ModelSetting &s : model_settings())
      if (s.key == key)
        for (dynamics::BodyModel m : s.models)
          models += (models.empty() ? "" : ", ") + std::string(dynamics::model_name(m));
    list += (list.empty() ? "" : ", ") + key + " (" + models + ")";
  }
  if (list.empty()) return "";
  std::string model = std::string("model: ") + dynamics::model_name(body.model);
  if (dynamics::simulated_model(body.model) != body.model)
    model += std::string(", simulated as ") +
             dynamics::model_name(dynamics::simulated_model(body.model));
  return "body " + body.name + " (" + model + "): settings not used by this model: " + list;
}

namespace {

using detail::has_body;
using detail::Reader;

/// Keys of CASE_FORMAT.md that belong to later stages (dynamic optimization): recognised so that
/// the message says they are not available yet rather than "unknown".
const std::set<std::string> kNotYetSupported = {};

/// Top-level keys that only a dynamic analysis takes.
const char *const kDynamicOnly[] = {"ground", "joints", "drivers", "time", "accuracy"};

/// Top-level keys of the static analysis that a dynamic analysis does not take.
const char *const kStaticOnly[] = {"supports", "tractions", "line_loads"};

/// The case directory, its name and case.yaml (into c.directory, c.name, c.file), parsed.
YAML::Node open_case(const std::string &directory, Case &c) {
  c.directory = directory;
  fs::path dir(directory);
  if (!fs::is_directory(dir))
    throw Error("case directory '" + directory + "' does not exist", true);
  c.name = fs::absolute(dir).lexically_normal().filename().string();
  if (c.name.empty())
    c.name = fs::absolute(dir).lexically_normal().parent_path().filename().string();
  c.file = (dir / "case.yaml").string();
  if (!fs::is_regular_file(c.file))
    throw Error(c.file + ": file not found (a case directory holds case.yaml)", true);

  YAML::Node root;
  try {
    root = YAML::LoadFile(c.file);
  } catch (const YAML::ParserException &e) {
    throw Error(c.file + ":" + std::to_string(e.mark.line + 1) + ":" +
                    std::to_string(e.mark.column + 1) + ": YAML syntax error: " + e.msg,
                true);
  }
  return root;
}

/// The top level of case.yaml: a mapping of known keys, `analysis` (into c.analysis), and the
/// keys that only the other analysis takes.
void read_top_level(const Reader &r, YAML::Node root, Case &c) {
  if (!root.IsMap())
    throw Error(c.file + ":1:1: expected a mapping of keys (analysis, materials, bodies, ...)",
                true);

  for (const auto &kv : root) {
    const std::string key = kv.first.as<std::string>();
    if (kNotYetSupported.count(key))
      r.fail(kv.first, "key '" + key +
                           "' is part of the case format but not supported yet by this version of "
                           "flexopt");
  }
  r.check_keys(root, "",
               {"analysis", "materials", "bodies",    "ground",     "joints",      "drivers",
                "loads",    "supports",  "tractions", "line_loads", "time",        "sensors",
                "output",   "solver",    "design",    "objective",  "constraints", "optimizer",
                "adjoint",  "accuracy",  "scenarios", "load_cases"});

  c.analysis =
      r.enumerated(r.require(root, "analysis", ""), "analysis",
                   {std::pair{"static", Analysis::Static}, {"dynamic", Analysis::Dynamic}});
  c.scene.file = c.file;
  const bool dynamic = c.dynamic();
  for (const char *key : kDynamicOnly)
    if (!dynamic && root[key])
      r.fail(r.key_node(root, key),
             std::string(key) + ": needs analysis: dynamic (this case is static)");
  for (const char *key : kStaticOnly)
    if (dynamic && root[key])
      r.fail(r.key_node(root, key), std::string(key) + ": not supported yet in a dynamic analysis");
}

/// `supports:` (a static analysis's fixed surfaces) into c.loads.supports.
void read_supports(const Reader &r, const YAML::Node &node, Case &c,
                   const std::string &key = "supports") {
  r.require_sequence(node, key);
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = key + "[" + std::to_string(i) + "]";
    r.require_map(v, path);
    r.check_keys(v, path, {"body", "surface", "fix"});
    fem::Support s;
    s.where = r.where(v);
    const std::string body = r.string(r.require(v, "body", path), path + ".body");
    if (!has_body(c, body)) r.fail(v["body"], path + ".body: no body named '" + body + "'");
    s.surface = r.string(r.require(v, "surface", path), path + ".surface");
    auto fix = r.string_list(r.require(v, "fix", path), path + ".fix");
    if (fix.empty()) r.fail(v["fix"], path + ".fix: name at least one of x, y, z");
    for (std::size_t k = 0; k < fix.size(); ++k) {
      const std::string &f = fix[k];
      if (f == "x")
        s.fix[0] = true;
      else if (f == "y")
        s.fix[1] = true;
      else if (f == "z")
        s.fix[2] = true;
      else
        r.fail(v["fix"][k], path + ".fix: '" + f + "' is not one of x, y, z");
    }
    c.loads.supports.push_back(s);
  }
}

/// `tractions:` (`where_key` surface) or `line_loads:` (curve) of a static analysis into `out`.
void read_tractions(const Reader &r, const YAML::Node &node, Case &c, const std::string &key,
                    const char *where_key, std::vector<fem::SurfaceLoad> &out) {
  r.require_sequence(node, key);
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = key + "[" + std::to_string(i) + "]";
    r.require_map(v, path);
    const bool surface = std::string(where_key) == "surface";
    if (surface)
      r.check_keys(v, path, {"body", where_key, "value", "force", "moment"});
    else
      r.check_keys(v, path, {"body", where_key, "value"});
    fem::SurfaceLoad t;
    t.where = r.where(v);
    const std::string body = r.string(r.require(v, "body", path), path + ".body");
    if (!has_body(c, body)) r.fail(v["body"], path + ".body: no body named '" + body + "'");
    t.surface = r.string(r.require(v, where_key, path), path + "." + where_key);
    if (surface && v["force"]) {
      if (v["value"])
        r.fail(v["force"], path + ": give either value (force per area) or force (the total "
                                  "force, spread uniformly over the surface), not both");
      t.total = true;
      t.value = r.vector3(v["force"], path + ".force");
      if (v["moment"]) t.moment = r.vector3(v["moment"], path + ".moment");
    } else {
      if (surface && v["moment"])
        r.fail(v["moment"], path + ".moment: a moment goes with force (the total force and the "
                                   "moment about the surface's centroid), not with value");
      t.value = r.vector3(r.require(v, "value", path), path + ".value");
    }
    out.push_back(t);
  }
}

/// `load_cases:` of a static analysis: each a name and the supports, tractions, line loads and
/// gravity it gives instead of the case's (a key not given keeps the case's).
void read_load_cases(const Reader &r, const YAML::Node &node, Case &c) {
  r.require_sequence(node, "load_cases");
  if (node.size() == 0) r.fail(node, "load_cases: list at least one load case");
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = "load_cases[" + std::to_string(i) + "]";
    r.require_map(v, path);
    r.check_keys(v, path, {"name", "supports", "tractions", "line_loads", "gravity"});
    LoadCase lc;
    lc.where = r.where(v);
    lc.name = r.string(r.require(v, "name", path), path + ".name");
    for (std::size_t k = 0; k < c.load_cases.size(); ++k)
      if (c.load_cases[k].name == lc.name)
        r.fail(v["name"], path + ".name: two load cases are named '" + lc.name + "' (load_cases[" +
                              std::to_string(k) + "])");
    Case one = c; // the case's loads, each given key replacing its part
    if (v["supports"]) {
      one.loads.supports.clear();
      read_supports(r, v["supports"], one, path + ".supports");
    }
    if (v["tractions"]) {
      one.loads.tractions.clear();
      read_tractions(r, v["tractions"], one, path + ".tractions", "surface", one.loads.tractions);
    }
    if (v["line_loads"]) {
      one.loads.line_loads.clear();
      read_tractions(r, v["line_loads"], one, path + ".line_loads", "curve", one.loads.line_loads);
    }
    if (v["gravity"]) one.loads.gravity = r.vector3(v["gravity"], path + ".gravity");
    lc.loads = one.loads;
    c.load_cases.push_back(lc);
  }
}

/// `loads:` (gravity; a static analysis's inertia, a dynamic one's interface forces).
void read_loads(const Reader &r, const YAML::Node &l, Case &c) {
  const bool dynamic = c.dynamic();
  r.require_map(l, "loads");
  r.check_keys(l, "loads", {"gravity", "forces", "inertia"});
  if (l["gravity"]) {
    const std::array<double, 3> g = r.vector3(l["gravity"], "loads.gravity");
    (dynamic ? c.scene.gravity : c.loads.gravity) = g;
  }
  if (l["inertia"]) {
    const YAML::Node &n = l["inertia"];
    if (dynamic)
      r.fail(r.key_node(l, "inertia"),
             "loads.inertia: needs analysis: static (a dynamic analysis computes the inertia "
             "of its bodies itself)");
    const std::string path = "loads.inertia";
    r.require_map(n, path);
    r.check_keys(n, path, {"point", "acceleration", "angular_velocity", "angular_acceleration"});
    fem::RigidMotion in;
    in.where = r.where(n);
    if (n["point"]) in.point = r.vector3(n["point"], path + ".point");
    if (n["acceleration"]) in.acceleration = r.vector3(n["acceleration"], path + ".acceleration");
    if (n["angular_velocity"])
      in.angular_velocity = r.vector3(n["angular_velocity"], path + ".angular_velocity");
    if (n["angular_acceleration"])
      in.angular_acceleration =
          r.vector3(n["angular_acceleration"], path + ".angular_acceleration");
    c.loads.inertia = in;
  }
  if (l["forces"]) {
    if (!dynamic)
      r.fail(r.key_node(l, "forces"),
             "loads.forces: needs analysis: dynamic (this case is static)");
    detail::read_forces(r, l["forces"], c);
  }
}

} // namespace

/// `time:` (the grid and the integrator's settings of a dynamic analysis) at `path` into t;
/// `partial` (a scenario's time): every key optional, t holding the case's values.
void detail::read_time(const Reader &r, const YAML::Node &v, const std::string &path,
                       dynamics::TimeSettings &t, bool partial) {
  r.require_map(v, path);
  r.check_keys(v, path, {"end", "step", "rho_inf", "newton_reuse"});
  t.where = r.where(v);
  if (!partial || v["end"]) {
    t.end = r.number(r.require(v, "end", path), path + ".end");
    if (!(t.end > 0)) r.fail(v["end"], path + ".end: must be positive");
  }
  if (!partial || v["step"]) {
    t.step = r.number(r.require(v, "step", path), path + ".step");
    if (!(t.step > 0)) r.fail(v["step"], path + ".step: must be positive");
  }
  if (!(t.step <= t.end)) {
    char end[32];
    std::snprintf(end, sizeof end, "%g", t.end);
    r.fail(v["step"] ? v["step"] : v["end"],
           path + ".step: must not exceed " +
               (partial ? std::string("the scenario's end time (") + end + " s)"
                        : "time.end (" + v["end"].Scalar() + ")"));
  }
  if (v["rho_inf"]) {
    t.rho_inf = r.number(v["rho_inf"], path + ".rho_inf");
    if (!(t.rho_inf >= 0 && t.rho_inf <= 1))
      r.fail(v["rho_inf"], path + ".rho_inf: must lie in [0, 1] (1: no numerical damping; 0: "
                                  "the strongest)");
  }
  if (v["newton_reuse"]) {
    t.newton_reuse = r.number(v["newton_reuse"], path + ".newton_reuse");
    if (!(t.newton_reuse >= 0 && t.newton_reuse < 1))
      r.fail(v["newton_reuse"], path + ".newton_reuse: must lie in [0, 1) (0: a new iteration "
                                       "matrix every Newton iteration)");
  }
  t.given = true;
}

namespace {

/// `output:` (every N steps, or an interval of simulated time) into c.output.
void read_output(const Reader &r, const YAML::Node &o, bool dynamic, Case &c) {
  r.require_map(o, "output");
  r.check_keys(o, "output", {"every", "interval"});
  if (o["every"] && o["interval"])
    r.fail(r.key_node(o, "interval"),
           "output: give either every (steps) or interval (seconds), not both");
  if (o["every"]) {
    c.output.every = r.integer(o["every"], "output.every");
    if (c.output.every < 1) r.fail(o["every"], "output.every: must be >= 1");
  }
  if (o["interval"]) {
    if (!dynamic)
      r.fail(r.key_node(o, "interval"),
             "output.interval: needs analysis: dynamic (a static case writes per design "
             "iteration: use output.every)");
    c.output.interval = r.number(o["interval"], "output.interval");
    if (!(c.output.interval > 0))
      r.fail(o["interval"], "output.interval: must be positive (seconds of simulated time)");
  }
}

} // namespace

fem::StaticSettings static_settings(const Case &c) {
  const dynamics::BodyDescription &body = c.scene.bodies.front();
  return fem::StaticSettings{body.mesh, body.material, c.loads, c.file};
}

optimize::TopologySettings topology_settings(const Case &c) {
  if (c.design.empty() || !c.objective)
    throw Error(c.file + ": topology optimization needs design: and objective: sections", true);
  // A static case has one body, and the reader refuses two entries on one body.
  return optimize::TopologySettings{static_settings(c), c.design.front(), *c.objective,
                                    c.constraints};
}

adjoint::DynamicSettings dynamic_settings(const Case &c) {
  if (c.design.empty() || !c.objective)
    throw Error(c.file + ": an optimization needs design: and objective: sections", true);
  return adjoint::DynamicSettings{c.scene,      c.time,        c.design,
                                  *c.objective, c.constraints, c.adjoint};
}

plan::PlanSettings plan_settings(const Case &c) {
  plan::PlanSettings s{c.scene, c.time, c.accuracy, {}};
  for (const optimize::DesignSettings &d : c.design) s.design_bodies.push_back(d.body);
  return s;
}

Case load_case(const std::string &directory) {
  Case c;
  YAML::Node root = open_case(directory, c);
  const Reader r(c.file);
  read_top_level(r, root, c);
  const bool dynamic = c.dynamic();
  detail::read_materials(r, r.require(root, "materials", ""), c);
  detail::read_bodies(r, r.require(root, "bodies", ""), fs::path(directory), c);
  if (root["ground"]) detail::read_ground(r, root["ground"], c);
  if (root["joints"]) detail::read_joints(r, root["joints"], c);
  if (root["drivers"]) detail::read_drivers(r, root["drivers"], c);
  if (root["loads"]) read_loads(r, root["loads"], c);
  if (root["time"]) detail::read_time(r, root["time"], "time", c.time, false);
  if (root["supports"]) read_supports(r, root["supports"], c);
  if (root["tractions"])
    read_tractions(r, root["tractions"], c, "tractions", "surface", c.loads.tractions);
  if (root["line_loads"])
    read_tractions(r, root["line_loads"], c, "line_loads", "curve", c.loads.line_loads);
  if (root["sensors"]) detail::read_sensors(r, root["sensors"], c);
  if (root["scenarios"]) {
    if (!dynamic)
      r.fail(r.key_node(root, "scenarios"),
             "scenarios: needs analysis: dynamic (a static case's conditions are load_cases:)");
    detail::read_scenarios(r, root["scenarios"], c);
  }
  if (root["load_cases"]) {
    if (dynamic)
      r.fail(r.key_node(root, "load_cases"),
             "load_cases: needs analysis: static (a dynamic case's operating conditions are "
             "scenarios:, each changing drivers, loads, gravity, initial speeds, densities or "
             "time)");
    read_load_cases(r, root["load_cases"], c);
  }
  if (root["output"]) read_output(r, root["output"], dynamic, c);
  if (root["solver"]) c.solver = r.string(root["solver"], "solver");
  if (root["accuracy"]) {
    c.accuracy = r.number(root["accuracy"], "accuracy");
    if (!(c.accuracy > 0 && c.accuracy < 1))
      r.fail(root["accuracy"], "accuracy: the accepted relative error of the sensors must lie in "
                               "(0, 1), e.g. 1e-2");
  }
  detail::read_optimization(r, root, c);

  if (!dynamic && c.scene.bodies.size() != 1)
    r.fail(root["bodies"], "bodies: a static analysis takes exactly one body (got " +
                               std::to_string(c.scene.bodies.size()) + ")");
  if (dynamic && !c.time.given)
    r.fail(root["analysis"], "analysis: a dynamic analysis needs time: {end: T, step: h}");
  return c;
}

} // namespace flexopt::io
