/// \file case.yaml's optimization (docs/case-format.md): design, objective, constraints,
/// optimizer and adjoint.
#include "case_sections.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <string>

namespace flexopt::io::detail {

namespace {

using dynamics::BodyModel;
using dynamics::SensorQuantity;

/// One entry of `design:` at `path` (the design body, region, interpolation, filter and
/// projection) into c.design.
void read_design_entry(const Reader &r, const YAML::Node &v, const std::string &path, Case &c) {
  r.require_map(v, path);
  r.check_keys(v, path, {"body", "region", "initial", "interpolation", "filter", "projection"});
  optimize::DesignSettings d;
  d.where = r.where(v);
  d.body = r.string(r.require(v, "body", path), path + ".body");
  if (!has_body(c, d.body)) r.fail(v["body"], path + ".body: no body named '" + d.body + "'");
  for (std::size_t k = 0; k < c.design.size(); ++k)
    if (c.design[k].body == d.body)
      r.fail(v["body"], path + ".body: body '" + d.body + "' has a design already (design[" +
                            std::to_string(k) + "], " + c.design[k].where.str() +
                            "): one entry per design body");
  d.region_where = d.where;
  if (v["region"]) {
    d.region = r.string(v["region"], path + ".region");
    d.region_where = r.where(v["region"]);
  }
  if (v["initial"]) {
    d.initial = r.number(v["initial"], path + ".initial");
    if (!(d.initial > 0 && d.initial <= 1))
      r.fail(v["initial"], path + ".initial: must lie in (0, 1]");
  }
  // The mass interpolation's default: a flexible design body in a dynamic analysis gets the one
  // that keeps its lowest modes global (docs/theory.md 9.1, "Local modes"); a rigid one has no
  // modes, and its mass is best exactly the densities'.
  for (const dynamics::BodyDescription &b : c.scene.bodies)
    if (b.name == d.body && c.dynamic() && dynamics::simulated_model(b.model) != BodyModel::Rigid)
      d.mass = optimize::MassInterpolation::Pedersen;
  // A static design under body forces (self-weight, inertia): a void element's load w(rho) f_e
  // must vanish faster than its SIMP stiffness, or it deforms without bound (docs/theory.md
  // section 5); the Du-Olhoff form (rho^6 below 0.1) does, a linear mass does not.
  if (!c.dynamic() && (c.loads.gravity || c.loads.inertia))
    d.mass = optimize::MassInterpolation::Pedersen;
  if (v["interpolation"]) {
    const YAML::Node &i = v["interpolation"];
    const std::string ip = path + ".interpolation";
    r.require_map(i, ip);
    r.check_keys(i, ip, {"penalty", "min_stiffness", "mass", "stress_exponent"});
    if (i["penalty"]) {
      d.penalty = r.number(i["penalty"], ip + ".penalty");
      if (!(d.penalty >= 1)) r.fail(i["penalty"], ip + ".penalty: the SIMP exponent must be >= 1");
    }
    if (i["min_stiffness"]) {
      d.min_stiffness = r.number(i["min_stiffness"], ip + ".min_stiffness");
      if (!(d.min_stiffness > 0 && d.min_stiffness < 1))
        r.fail(i["min_stiffness"], ip + ".min_stiffness: E_min / E_0 must lie in (0, 1)");
    }
    if (i["stress_exponent"]) {
      d.stress_exponent = r.number(i["stress_exponent"], ip + ".stress_exponent");
      if (!(d.stress_exponent > 0 && d.stress_exponent < d.penalty))
        r.fail(i["stress_exponent"],
               ip + ".stress_exponent: the stress relaxation exponent q must lie in (0, penalty) "
                    "(the qp-approach: q < p; docs/theory.md 5.1)");
    }
    if (i["mass"])
      d.mass = r.enumerated(i["mass"], ip + ".mass",
                            {std::pair{"linear", optimize::MassInterpolation::Linear},
                             {"pedersen", optimize::MassInterpolation::Pedersen}});
  }
  // Without filter: or its radius, DesignField takes a radius from the design elements' size
  // (filter_radius 0 here).
  if (const YAML::Node &f = v["filter"]) {
    r.require_map(f, path + ".filter");
    r.check_keys(f, path + ".filter", {"type", "radius"});
    if (f["type"])
      d.filter_type = r.enumerated(f["type"], path + ".filter.type",
                                   {std::pair{"helmholtz", optimize::FilterType::Helmholtz},
                                    {"cone", optimize::FilterType::Cone}});
    if (f["radius"]) {
      d.filter_radius = r.number(f["radius"], path + ".filter.radius");
      if (!(d.filter_radius > 0)) r.fail(f["radius"], path + ".filter.radius: must be positive");
    }
  }
  if (v["projection"]) {
    const YAML::Node &p = v["projection"];
    const std::string pp = path + ".projection";
    r.require_map(p, pp);
    r.check_keys(p, pp, {"beta", "eta", "every"});
    const YAML::Node &b = r.require(p, "beta", pp);
    r.require_sequence(b, pp + ".beta");
    if (b.size() == 0) r.fail(b, pp + ".beta: give at least one value");
    for (std::size_t k = 0; k < b.size(); ++k) {
      d.beta.push_back(r.number(b[k], pp + ".beta[" + std::to_string(k) + "]"));
      if (!(d.beta.back() > 0)) r.fail(b[k], pp + ".beta: values must be positive");
    }
    if (p["every"]) {
      d.beta_every = r.integer(p["every"], pp + ".every");
      if (d.beta_every < 1) r.fail(p["every"], pp + ".every: must be >= 1");
    }
    if (p["eta"]) {
      d.eta = r.number(p["eta"], pp + ".eta");
      if (!(d.eta > 0 && d.eta < 1)) r.fail(p["eta"], pp + ".eta: must lie in (0, 1)");
    }
    // One continuation for every design body (docs/theory.md 9.9): one `every`.
    for (const optimize::DesignSettings &o : c.design)
      if (!o.beta.empty() && o.beta_every != d.beta_every)
        r.fail(p["every"] ? p["every"] : p, pp + ".every: " + std::to_string(d.beta_every) +
                                                ", but design of body '" + o.body + "' has " +
                                                std::to_string(o.beta_every) +
                                                ": the projection's stages run together, "
                                                "give every design entry the same every");
  }
  c.design.push_back(d);
}

/// `design:`: one map (one design body) or a list of them (several, docs/theory.md 9.9).
void read_design(const Reader &r, const YAML::Node &v, Case &c) {
  if (!v.IsSequence()) {
    read_design_entry(r, v, "design", c);
    return;
  }
  if (v.size() == 0) r.fail(v, "design: an empty list (give one entry per design body)");
  for (std::size_t k = 0; k < v.size(); ++k)
    read_design_entry(r, v[k], "design[" + std::to_string(k) + "]", c);
}

/// `body:` of a mass, strain_energy_integral or volume_fraction response: one body or a list,
/// each a body of the scene (volume_fraction: a design body), into s.bodies (s.body when one).
void read_response_bodies(const Reader &r, const YAML::Node &v, const std::string &path,
                          const Case &c, optimize::ResponseSettings &s) {
  const YAML::Node &b = v["body"];
  const bool design_only = s.type == optimize::ResponseType::VolumeFraction;
  auto one = [&](const YAML::Node &n, const std::string &at) {
    const std::string name = r.string(n, at);
    if (!has_body(c, name)) r.fail(n, at + ": no body named '" + name + "'");
    bool designed = false;
    for (const optimize::DesignSettings &d : c.design) designed = designed || d.body == name;
    if (design_only && !designed) {
      std::string list;
      for (const optimize::DesignSettings &d : c.design)
        list += (list.empty() ? "" : ", ") + d.body;
      r.fail(n, at + ": body '" + name + "' has no design (design: names " +
                    (list.empty() ? std::string("none") : list) +
                    "); a volume fraction is one of design regions");
    }
    if (std::find(s.bodies.begin(), s.bodies.end(), name) != s.bodies.end())
      r.fail(n, at + ": body '" + name + "' is named twice");
    s.bodies.push_back(name);
  };
  if (b.IsSequence()) {
    if (b.size() == 0) r.fail(b, path + ".body: an empty list");
    for (std::size_t k = 0; k < b.size(); ++k) one(b[k], path + ".body[" + std::to_string(k) + "]");
  } else {
    one(b, path + ".body");
    s.body = s.bodies.front();
  }
}

/// A stress response's keys (docs/case-format.md "Stress responses") into s: the body (optional
/// for a single-body static case), the aggregate and its parameter, the normalization, the
/// reference stress and the region.
void read_stress(const Reader &r, const YAML::Node &v, const std::string &path, bool constraint,
                 const Case &c, optimize::ResponseSettings &s) {
  if (v["body"]) {
    s.body = r.string(v["body"], path + ".body");
    if (!has_body(c, s.body)) r.fail(v["body"], path + ".body: no body named '" + s.body + "'");
  } else if (c.dynamic() || c.scene.bodies.size() != 1) {
    r.fail(v, path + ": a stress response in a scene of several bodies (or a dynamic one) names "
                     "its body: add body: <name>");
  } else {
    s.body = c.scene.bodies.front().name;
  }
  for (const dynamics::BodyDescription &b : c.scene.bodies)
    if (b.name == s.body && c.dynamic() && b.model == BodyModel::Rigid)
      r.fail(v["body"], path + ".body: '" + s.body +
                            "' is a rigid body, which has no stress: a stress response needs an "
                            "FFRF or ACF body (model: ffrf or acf)");
  optimize::StressAggregateSettings &a = s.aggregate;
  if (v["aggregate"])
    a.type = r.enumerated(v["aggregate"], path + ".aggregate",
                          {std::pair{"pnorm", optimize::StressAggregateType::PNorm},
                           {"ks", optimize::StressAggregateType::Ks}});
  const bool ks = a.type == optimize::StressAggregateType::Ks;
  if (v["p"]) {
    if (ks) r.fail(v["p"], path + ".p: the p-norm's exponent; aggregate: ks takes ks:");
    a.p = r.number(v["p"], path + ".p");
    if (!(a.p >= 1 && a.p <= 200))
      r.fail(v["p"], path + ".p: the p-norm's exponent must lie in [1, 200] (8 is usual)");
  }
  if (v["ks"]) {
    if (!ks) r.fail(v["ks"], path + ".ks: the KS parameter; it needs aggregate: ks");
    a.ks = r.number(v["ks"], path + ".ks");
    if (!(a.ks > 0 && a.ks <= 1e4))
      r.fail(v["ks"], path + ".ks: must lie in (0, 1e4] (20 is usual)");
  }
  if (v["normalization"])
    s.adaptive = r.enumerated(v["normalization"], path + ".normalization",
                              {std::pair{"none", false}, {"adaptive", true}});
  if (v["reference"]) {
    if (!ks) r.fail(v["reference"], path + ".reference: only aggregate: ks takes it");
    a.reference = r.number(v["reference"], path + ".reference");
    if (!(a.reference > 0 && std::isfinite(a.reference)))
      r.fail(v["reference"], path + ".reference: must be a positive stress [Pa]");
  } else if (ks && !constraint) {
    r.fail(v, path + ": a ks stress objective needs reference: <stress> [Pa], the stress its ks "
                     "parameter is relative to (a constraint takes its max)");
  }
  if (v["region"]) s.region = r.string(v["region"], path + ".region");
}

/// A constraint's bound `max` into s (the objective takes none), checked for the response's type;
/// a KS stress constraint's reference stress is its bound unless given.
void read_bound(const Reader &r, const YAML::Node &v, const std::string &path, bool constraint,
                optimize::ResponseSettings &s) {
  using optimize::ResponseType;
  if (!constraint) {
    if (v["max"]) r.fail(v["max"], path + ".max: the objective takes no bound");
    return;
  }
  s.max = r.number(r.require(v, "max", path), path + ".max");
  s.has_max = true;
  if (s.type == ResponseType::VolumeFraction && !(s.max > 0 && s.max < 1))
    r.fail(v["max"], path + ".max: a volume fraction bound must lie in (0, 1)");
  if (s.type == ResponseType::Mass && !(s.max > 0))
    r.fail(v["max"], path + ".max: a mass bound must be positive [kg]");
  if (s.type == ResponseType::Stress && !(s.max > 0 && std::isfinite(s.max)))
    r.fail(v["max"], path + ".max: a stress limit must be a positive number [Pa]");
  if (s.type == ResponseType::Stress && s.aggregate.reference == 0) s.aggregate.reference = s.max;
}

/// The objective or a constraint (`constraint`: with its bound `max`) at `path`.
optimize::ResponseSettings read_response(const Reader &r, const YAML::Node &v,
                                         const std::string &path, bool constraint, const Case &c) {
  using optimize::ResponseType;
  r.require_map(v, path);
  r.check_keys(v, path,
               {"type", "sensor", "direction", "body", "target", "component", "measure", "ks",
                "max", "aggregate", "p", "normalization", "reference", "region", "scenarios",
                "load_cases", "combine", "weights", "combine_ks"});
  optimize::ResponseSettings s;
  s.where = r.where(v);
  const bool dynamic = c.dynamic();
  s.type = r.enumerated(r.require(v, "type", path), path + ".type",
                        {std::pair{"compliance", ResponseType::Compliance},
                         {"volume_fraction", ResponseType::VolumeFraction},
                         {"displacement", ResponseType::Displacement},
                         {"strain_energy_integral", ResponseType::StrainEnergyIntegral},
                         {"tracking_error", ResponseType::TrackingError},
                         {"sensor", ResponseType::Sensor},
                         {"mass", ResponseType::Mass},
                         {"stress", ResponseType::Stress}});
  const std::string type = optimize::response_type_name(s.type);
  const bool dynamic_only = s.type == ResponseType::StrainEnergyIntegral ||
                            s.type == ResponseType::TrackingError || s.type == ResponseType::Sensor;
  if (!dynamic && dynamic_only)
    r.fail(v["type"], path + ".type: '" + type + "' is a response of a dynamic analysis");
  if (dynamic && (s.type == ResponseType::Compliance || s.type == ResponseType::Displacement))
    r.fail(v["type"], path + ".type: '" + type +
                          "' is a response of a static analysis (dynamic: strain_energy_integral, "
                          "tracking_error, sensor, volume_fraction, mass)");
  // Which keys each type takes.
  std::set<std::string> takes;
  if (s.type == ResponseType::Displacement) takes = {"sensor", "direction"};
  if (s.type == ResponseType::TrackingError) takes = {"sensor", "target"};
  if (s.type == ResponseType::Sensor) takes = {"sensor", "component", "measure", "ks"};
  if (s.type == ResponseType::StrainEnergyIntegral || s.type == ResponseType::Mass ||
      s.type == ResponseType::VolumeFraction)
    takes = {"body"};
  if (s.type == ResponseType::Stress)
    takes = {"body", "aggregate", "p", "ks", "normalization", "reference", "region"};
  // `ks` of a type that has no KS parameter is the scenario combination's (combine: max).
  const bool ks_taken = takes.count("ks") > 0;
  if (!ks_taken && !condition_names(c).empty()) takes.insert("ks");
  for (const char *k : {"sensor", "direction", "body", "target", "component", "measure", "ks",
                        "aggregate", "p", "normalization", "reference", "region"})
    if (v[k] && !takes.count(k))
      r.fail(v[k], path + "." + k + ": a '" + type + "' response does not take it");
  auto find_sensor = [&]() {
    s.sensor = r.string(r.require(v, "sensor", path), path + ".sensor");
    for (const auto &sensor : c.scene.sensors)
      if (sensor.name == s.sensor) {
        if (dynamic && (sensor.quantity == SensorQuantity::RotationAngle ||
                        sensor.quantity == SensorQuantity::Reaction))
          r.fail(v["sensor"], path + ".sensor: sensor '" + s.sensor + "' measures " +
                                  dynamics::quantity_name(sensor.quantity) +
                                  ", which a response cannot use yet (position, displacement, "
                                  "elastic_displacement)");
        s.point = sensor.point;
        s.point_where = sensor.where;
        return;
      }
    r.fail(v["sensor"], path + ".sensor: no sensor named '" + s.sensor + "'");
  };
  if (s.type == ResponseType::Displacement) {
    find_sensor();
    s.direction = r.direction(r.require(v, "direction", path), path + ".direction");
  }
  if (s.type == ResponseType::TrackingError) {
    find_sensor();
    const YAML::Node &tg = r.require(v, "target", path);
    if (!tg.IsSequence() || tg.size() != 3)
      r.fail(tg, path + ".target: expected a list of 3 components [x, y, z], each a number or an "
                        "expression in t");
    for (std::size_t k = 0; k < 3; ++k) {
      const std::string kp = path + ".target[" + std::to_string(k) + "]";
      s.target[k] = r.expression(tg[k], kp);
      if (c.time.given)
        for (double t : {0.0, 0.5 * c.time.end, c.time.end}) {
          const double y = Expression(s.target[k])(t);
          if (!std::isfinite(y)) {
            char buf[64];
            std::snprintf(buf, sizeof buf, "%g s (%g)", t, y);
            r.fail(tg[k], kp + ": '" + s.target[k] + "' is not finite at t = " + buf);
          }
        }
    }
  }
  if (s.type == ResponseType::Sensor) {
    find_sensor();
    const YAML::Node &cn = r.require(v, "component", path);
    const std::string cs = cn.IsScalar() ? cn.Scalar() : "";
    if (cs == "0" || cs == "x")
      s.component = 0;
    else if (cs == "1" || cs == "y")
      s.component = 1;
    else if (cs == "2" || cs == "z")
      s.component = 2;
    else
      r.fail(cn, path + ".component: expected 0, 1, 2 (or x, y, z), got '" + cs + "'");
    s.measure = r.enumerated(r.require(v, "measure", path), path + ".measure",
                             {std::pair{"final", optimize::SensorMeasure::Final},
                              {"mean_square", optimize::SensorMeasure::MeanSquare},
                              {"ks_max", optimize::SensorMeasure::KsMax}});
    if (v["ks"]) {
      if (s.measure != optimize::SensorMeasure::KsMax)
        r.fail(v["ks"], path + ".ks: only measure: ks_max takes it");
      s.ks = r.number(v["ks"], path + ".ks");
      if (!(s.ks > 0)) r.fail(v["ks"], path + ".ks: must be positive");
    }
  }
  if (s.type == ResponseType::StrainEnergyIntegral || s.type == ResponseType::Mass) {
    r.require(v, "body", path);
    read_response_bodies(r, v, path, c, s);
  }
  if (s.type == ResponseType::VolumeFraction && v["body"]) read_response_bodies(r, v, path, c, s);
  if (s.type == ResponseType::Stress) read_stress(r, v, path, constraint, c, s);
  read_bound(r, v, path, constraint, s);
  read_response_conditions(r, v, path, c, constraint, ks_taken, s);
  return s;
}

/// `adjoint:` (the checkpointing of a dynamic optimization's backward sweep) into c.adjoint.
void read_adjoint(const Reader &r, const YAML::Node &v, Case &c) {
  const std::string path = "adjoint";
  r.require_map(v, path);
  r.check_keys(v, path, {"checkpoints", "storage", "basis"});
  adjoint::CheckpointSettings &a = c.adjoint;
  a.where = r.where(v);
  if (v["checkpoints"]) {
    const YAML::Node &n = v["checkpoints"];
    if (!(n.IsScalar() && n.Scalar() == "all")) {
      a.checkpoints = r.integer(n, path + ".checkpoints");
      if (a.checkpoints < 1)
        r.fail(n, path + ".checkpoints: must be 'all' or a number of stored states >= 1 (got " +
                      n.Scalar() + ")");
    }
  }
  if (v["storage"])
    a.storage = r.enumerated(v["storage"], path + ".storage",
                             {std::pair{"memory", adjoint::CheckpointStorage::Memory},
                              {"disk", adjoint::CheckpointStorage::Disk}});
  if (v["basis"])
    a.basis = r.enumerated(v["basis"], path + ".basis",
                           {std::pair{"exact", reduce::BasisDerivative::Exact},
                            {"fixed", reduce::BasisDerivative::Fixed}});
}

/// optimizer.method and the equivalent static loads' keys into c.esl (docs/theory.md 14): a
/// dynamic case with one design body that is not ACF, an objective of its strain energy.
void read_esl(const Reader &r, const YAML::Node &o, Case &c) {
  const bool esl = o["method"] && r.enumerated(o["method"], "optimizer.method",
                                               {std::pair{"mma", false}, {"esl", true}});
  for (const char *key : {"instants", "outer_iterations", "inner_iterations"})
    if (o[key] && !esl)
      r.fail(o[key], std::string("optimizer.") + key +
                         ": belongs to method: esl (equivalent static loads)");
  if (!esl) return;
  const YAML::Node &m = o["method"];
  if (!c.dynamic())
    r.fail(m, "optimizer.method: esl designs a body of a moving mechanism from its loads at "
              "instants of the motion: it needs analysis: dynamic (a static case is designed "
              "for its own loads already)");
  optimize::EslSettings e;
  e.where = r.where(m);
  auto count = [&](const char *key, int &value, int least) {
    if (!o[key]) return;
    value = r.integer(o[key], std::string("optimizer.") + key);
    if (value < least)
      r.fail(o[key], std::string("optimizer.") + key + ": must be >= " + std::to_string(least) +
                         " (got " + std::to_string(value) + ")");
  };
  count("instants", e.instants, 1);
  count("outer_iterations", e.outer_iterations, 1);
  count("inner_iterations", e.inner_iterations, 1);
  const double steps = c.time.given ? std::round(c.time.end / c.time.step) : 0;
  if (c.time.given && e.instants > steps)
    r.fail(o["instants"] ? o["instants"] : m, "optimizer.instants: " + std::to_string(e.instants) +
                                                  " instants, more than the run's " +
                                                  std::to_string(static_cast<long long>(steps)) +
                                                  " steps (one instant per step at most)");
  c.esl = e;
}

/// `optimizer:` into c.optimizer (the iterations, the move limit, the tolerance).
void read_optimizer(const Reader &r, const YAML::Node &o, Case &c) {
  r.require_map(o, "optimizer");
  r.check_keys(o, "optimizer",
               {"max_iterations", "move_limit", "tolerance", "method", "instants",
                "outer_iterations", "inner_iterations"});
  read_esl(r, o, c);
  if (o["max_iterations"]) {
    c.optimizer.max_iterations = r.integer(o["max_iterations"], "optimizer.max_iterations");
    if (c.optimizer.max_iterations < 1)
      r.fail(o["max_iterations"], "optimizer.max_iterations: must be >= 1");
  }
  if (o["move_limit"]) {
    c.optimizer.move_limit = r.number(o["move_limit"], "optimizer.move_limit");
    if (!(c.optimizer.move_limit > 0 && c.optimizer.move_limit <= 1))
      r.fail(o["move_limit"], "optimizer.move_limit: must lie in (0, 1]");
  }
  if (o["tolerance"]) {
    c.optimizer.tolerance = r.number(o["tolerance"], "optimizer.tolerance");
    if (!(c.optimizer.tolerance >= 0)) r.fail(o["tolerance"], "optimizer.tolerance: must be >= 0");
  }
}

/// What method: esl can design (docs/theory.md 14.6): one design body, rigid or FFRF (ACF's
/// loads are not built), an objective of its strain energy, constraints on its volume, mass or
/// stress, one motion (no scenarios), at most one instant per step.
void check_esl(const Reader &r, const YAML::Node &root, const Case &c) {
  const optimize::EslSettings &e = *c.esl;
  auto refuse = [&](const io::Location &where, const std::string &what) {
    throw Error(where.str() + ": " + what, true);
  };
  if (c.design.size() != 1)
    refuse(e.where, "optimizer.method: esl designs one body (design: names " +
                        std::to_string(c.design.size()) + ")");
  const std::string &body = c.design.front().body;
  for (const auto &b : c.scene.bodies)
    if (b.name == body && b.model == dynamics::BodyModel::Acf)
      refuse(e.where, "optimizer.method: esl: design body '" + body +
                          "' is model acf, whose loads at an instant are not built yet; use "
                          "model: ffrf or rigid for it, or method: mma");
  const optimize::ResponseSettings &o = *c.objective;
  if (o.type != optimize::ResponseType::StrainEnergyIntegral ||
      o.bodies != std::vector<std::string>{body})
    refuse(o.where, "objective: method: esl minimizes the design body's strain energy "
                    "(objective: {type: strain_energy_integral, body: " +
                        body + "}); the static designs approximate it");
  for (const optimize::ResponseSettings &k : c.constraints) {
    const bool design_only =
        k.type == optimize::ResponseType::VolumeFraction ||
        (k.type == optimize::ResponseType::Mass && k.bodies == std::vector<std::string>{body});
    const bool stress = k.type == optimize::ResponseType::Stress && k.body == body;
    if (!design_only && !stress)
      refuse(k.where, "constraints: method: esl takes the design body's volume_fraction, mass "
                      "and stress constraints (a static design has no motion to measure)");
  }
  if (root["scenarios"])
    refuse(r.where(root["scenarios"]), "scenarios: method: esl takes one motion (its instants are "
                                       "the load cases)");
}

} // namespace

void read_optimization(const Reader &r, YAML::Node root, Case &c) {
  const bool dynamic = c.dynamic();
  if (root["design"]) read_design(r, root["design"], c);
  if (root["objective"]) c.objective = read_response(r, root["objective"], "objective", false, c);
  if (root["constraints"]) {
    const YAML::Node &l = root["constraints"];
    r.require_sequence(l, "constraints");
    for (std::size_t i = 0; i < l.size(); ++i)
      c.constraints.push_back(
          read_response(r, l[i], "constraints[" + std::to_string(i) + "]", true, c));
  }
  if (root["optimizer"]) read_optimizer(r, root["optimizer"], c);
  if (root["adjoint"]) {
    if (!dynamic)
      r.fail(r.key_node(root, "adjoint"),
             "adjoint: needs analysis: dynamic (a static optimization stores no states)");
    read_adjoint(r, root["adjoint"], c);
  }
  if ((c.objective || !c.constraints.empty() || root["optimizer"]) && c.design.empty())
    r.fail(root, "objective/constraints/optimizer need a design: section (the design field)");
  if (!c.design.empty() && !c.objective)
    r.fail(root["design"], "design: an optimization needs an objective:");
  if (c.esl) check_esl(r, root, c);

  // Every condition is taken by some response (else it adds nothing but cost).
  if (c.objective) {
    const std::vector<std::string> names = condition_names(c);
    for (std::size_t k = 0; k < names.size(); ++k) {
      if (!condition_responses(c, k).empty()) continue;
      const io::Location &at = c.dynamic() ? c.scenarios[k].where : c.load_cases[k].where;
      throw Error(at.str() + ": " + condition_noun(c) + " '" + names[k] +
                      "' is taken by no response (objective and constraints name the ones "
                      "they take): it would cost a run and change nothing",
                  true);
    }
  }

  // The optimizer's share of other keys: the constraints' bounds, and design.xdmf's stride
  // (output.every counts iterations in a static analysis; in a dynamic one it counts the
  // motion's time steps and design.xdmf takes its default, docs/case-format.md "output").
  for (const optimize::ResponseSettings &con : c.constraints) c.optimizer.bounds.push_back(con.max);
  c.optimizer.output_every = dynamic ? 0 : c.output.every;
}

} // namespace flexopt::io::detail
