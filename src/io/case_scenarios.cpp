/// \file The operating conditions of a case (docs/case-format.md "Scenarios and load cases"):
/// `scenarios:` of a dynamic case, the responses' `scenarios:`/`load_cases:`, `combine:`,
/// `weights:` and KS parameter, and the case of one condition.
#include "case_reader.hpp"
#include "case_sections.hpp"
#include "flexopt/core/error.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace flexopt::io {

namespace detail {

namespace {

dynamics::BodyDescription &body_of(dynamics::SceneDescription &scene, const std::string &name) {
  for (dynamics::BodyDescription &b : scene.bodies)
    if (b.name == name) return b;
  throw Error("no body '" + name + "'", true);
}

/// A scenario's `drivers:`: each changes the expression of a driver the case has.
void read_scenario_drivers(const Reader &r, const YAML::Node &v, const std::string &path,
                           const Case &c, Scenario &s) {
  Case given; // the scenario's list, read (and checked) as drivers: are
  given.scene.joints = c.scene.joints;
  read_drivers(r, v, given, path);
  for (std::size_t j = 0; j < given.scene.drivers.size(); ++j) {
    const dynamics::DriverDescription &d = given.scene.drivers[j];
    auto it =
        std::find_if(s.scene.drivers.begin(), s.scene.drivers.end(),
                     [&](const dynamics::DriverDescription &e) { return e.joint == d.joint; });
    if (it == s.scene.drivers.end()) {
      std::vector<std::string> driven;
      for (const dynamics::DriverDescription &e : c.scene.drivers) driven.push_back(e.joint);
      r.fail(v[j]["joint"], path + "[" + std::to_string(j) + "].joint: joint '" + d.joint +
                                "' has no driver in drivers: (a scenario changes the case's "
                                "drivers; driven joints: " +
                                (driven.empty() ? std::string("none") : join(driven)) + ")");
    }
    it->expression = d.expression;
    it->where = d.where;
  }
}

/// A scenario's `bodies:`: per body its density and initial speeds.
void read_scenario_bodies(const Reader &r, const YAML::Node &v, const std::string &path,
                          const Case &c, Scenario &s) {
  r.require_map(v, path);
  for (const auto &kv : v) {
    const std::string name = kv.first.as<std::string>();
    const std::string bp = path + "." + name;
    if (!has_body(c, name)) r.fail(kv.first, bp + ": no body named '" + name + "'");
    const YAML::Node &b = kv.second;
    r.require_map(b, bp);
    r.check_keys(b, bp, {"density", "initial"});
    dynamics::BodyDescription &body = body_of(s.scene, name);
    if (b["density"]) {
      body.material.density = r.number(b["density"], bp + ".density");
      if (!(body.material.density > 0))
        r.fail(b["density"], bp + ".density: must be positive [kg/m^3]");
    }
    if (b["initial"]) {
      const YAML::Node &in = b["initial"];
      r.require_map(in, bp + ".initial");
      r.check_keys(in, bp + ".initial", {"velocity", "angular_velocity"});
      if (in["velocity"])
        body.initial.velocity = r.vector3(in["velocity"], bp + ".initial.velocity");
      if (in["angular_velocity"])
        body.initial.angular_velocity =
            r.vector3(in["angular_velocity"], bp + ".initial.angular_velocity");
    }
  }
}

/// Whether a scenario changes the density of body `name`.
bool density_varies(const Case &c, const std::string &name) {
  const double base = c.scene.body(name).material.density;
  for (const Scenario &s : c.scenarios)
    if (s.scene.body(name).material.density != base) return true;
  return false;
}

} // namespace

void read_scenarios(const Reader &r, const YAML::Node &node, Case &c) {
  r.require_sequence(node, "scenarios");
  if (node.size() == 0) r.fail(node, "scenarios: list at least one scenario");
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = "scenarios[" + std::to_string(i) + "]";
    r.require_map(v, path);
    r.check_keys(v, path, {"name", "drivers", "loads", "time", "bodies"});
    Scenario s;
    s.where = r.where(v);
    s.name = r.string(r.require(v, "name", path), path + ".name");
    if (s.name.empty() || s.name.find_first_of(" /\\.") != std::string::npos)
      r.fail(v["name"], path + ".name: '" + s.name +
                            "' names output files (motion.NAME.xdmf): give a word without "
                            "spaces, dots or slashes");
    for (std::size_t k = 0; k < c.scenarios.size(); ++k)
      if (c.scenarios[k].name == s.name)
        r.fail(v["name"], path + ".name: two scenarios are named '" + s.name + "' (scenarios[" +
                              std::to_string(k) + "])");
    s.scene = c.scene;
    s.time = c.time;
    if (v["drivers"]) read_scenario_drivers(r, v["drivers"], path + ".drivers", c, s);
    if (v["loads"]) {
      const YAML::Node &l = v["loads"];
      r.require_map(l, path + ".loads");
      r.check_keys(l, path + ".loads", {"gravity", "forces"});
      if (l["gravity"]) s.scene.gravity = r.vector3(l["gravity"], path + ".loads.gravity");
      if (l["forces"]) {
        Case given;
        given.scene.bodies = c.scene.bodies;
        read_forces(r, l["forces"], given, path + ".loads.forces");
        s.scene.forces = given.scene.forces;
      }
    }
    if (v["time"]) read_time(r, v["time"], path + ".time", s.time, true);
    if (v["bodies"]) read_scenario_bodies(r, v["bodies"], path + ".bodies", c, s);
    c.scenarios.push_back(s);
  }
}

void read_response_conditions(const Reader &r, const YAML::Node &v, const std::string &path,
                              const Case &c, bool constraint, bool ks_taken,
                              optimize::ResponseSettings &s) {
  using optimize::Combine;
  using optimize::ResponseType;
  const std::vector<std::string> names = condition_names(c);
  const bool dynamic = c.dynamic();
  const char *list_key = dynamic ? "scenarios" : "load_cases";
  const char *other_key = dynamic ? "load_cases" : "scenarios";
  const char *ks_key = ks_taken ? "combine_ks" : (v["combine_ks"] ? "combine_ks" : "ks");
  if (v[other_key])
    r.fail(r.key_node(v, other_key), path + "." + other_key + ": a " +
                                         (dynamic ? "dynamic" : "static") +
                                         " case's conditions are " + list_key + ":");
  if (names.empty()) {
    for (const char *k : {"scenarios", "load_cases", "combine", "weights", "combine_ks"})
      if (v[k])
        r.fail(r.key_node(v, k), path + "." + k + ": the case has no " + list_key +
                                     ": (a response combines the conditions the case lists)");
    return;
  }
  // A response of the design alone (a volume fraction; a mass whose densities no scenario
  // changes) is the same in every condition: it is evaluated once, in the first.
  bool design_only = s.type == ResponseType::VolumeFraction;
  if (s.type == ResponseType::Mass) {
    design_only = true;
    for (const std::string &b : s.bodies) design_only = design_only && !density_varies(c, b);
  }
  if (design_only) {
    for (const char *k : {list_key, "combine", "weights", "combine_ks"})
      if (v[k])
        r.fail(r.key_node(v, k), path + "." + k + ": a '" + optimize::response_type_name(s.type) +
                                     "' response is the same in every condition (no " + list_key +
                                     " changes it): it takes no " + k);
    if (!ks_taken && v["ks"])
      r.fail(v["ks"], path + ".ks: a '" + std::string(optimize::response_type_name(s.type)) +
                          "' response does not take it");
    s.scenarios = {0};
    return;
  }
  s.scenarios.clear();
  const YAML::Node &list = v[list_key];
  if (!list || (list.IsScalar() && list.Scalar() == "all")) {
    for (std::size_t k = 0; k < names.size(); ++k) s.scenarios.push_back(k);
  } else {
    const std::vector<std::string> given = r.string_list(list, path + "." + list_key);
    if (given.empty()) r.fail(list, path + "." + list_key + ": name at least one, or all");
    for (std::size_t j = 0; j < given.size(); ++j) {
      auto it = std::find(names.begin(), names.end(), given[j]);
      if (it == names.end())
        r.fail(list[j], path + "." + list_key + "[" + std::to_string(j) + "]: no " +
                            condition_noun(c) + " named '" + given[j] + "' (" + list_key + ": " +
                            join(names) + ")");
      const std::size_t k = static_cast<std::size_t>(it - names.begin());
      if (std::find(s.scenarios.begin(), s.scenarios.end(), k) != s.scenarios.end())
        r.fail(list[j], path + "." + list_key + ": '" + given[j] + "' is named twice");
      s.scenarios.push_back(k);
    }
  }
  // A constraint holds in every condition it takes unless it says otherwise (their maximum);
  // the objective sums them.
  s.combine = constraint ? Combine::Max : Combine::Sum;
  if (v["combine"])
    s.combine = r.enumerated(
        v["combine"], path + ".combine",
        {std::pair{"sum", Combine::Sum}, {"weighted", Combine::Weighted}, {"max", Combine::Max}});
  if (s.combine == Combine::Weighted) {
    const YAML::Node &w = v["weights"];
    if (!w)
      r.fail(v["combine"], path + ".combine: weighted needs weights: [...], one per " +
                               condition_noun(c) + " taken (" + std::to_string(s.scenarios.size()) +
                               ")");
    r.require_sequence(w, path + ".weights");
    if (w.size() != s.scenarios.size())
      r.fail(w, path + ".weights: " + std::to_string(w.size()) + " weights for " +
                    std::to_string(s.scenarios.size()) + " " + list_key);
    for (std::size_t j = 0; j < w.size(); ++j) {
      s.weights.push_back(r.number(w[j], path + ".weights[" + std::to_string(j) + "]"));
      if (!(s.weights.back() > 0))
        r.fail(w[j], path + ".weights[" + std::to_string(j) + "]: must be positive");
    }
  } else if (v["weights"]) {
    r.fail(v["weights"], path + ".weights: only combine: weighted takes weights");
  }
  if (v[ks_key]) {
    if (s.combine != Combine::Max)
      r.fail(v[ks_key], path + "." + ks_key + ": only combine: max takes it");
    s.combine_ks = r.number(v[ks_key], path + "." + ks_key);
    if (!(s.combine_ks > 0)) r.fail(v[ks_key], path + "." + ks_key + ": must be positive");
  }
}

} // namespace detail

const char *condition_noun(const Case &c) {
  return c.dynamic() ? "scenario" : "load case";
}

std::vector<std::string> condition_names(const Case &c) {
  std::vector<std::string> out;
  for (const Scenario &s : c.scenarios) out.push_back(s.name);
  for (const LoadCase &l : c.load_cases) out.push_back(l.name);
  return out;
}

namespace {
/// The objective, then the constraints (empty without an objective).
std::vector<const optimize::ResponseSettings *> all_responses(const Case &c) {
  std::vector<const optimize::ResponseSettings *> all;
  if (!c.objective) return all;
  all.push_back(&*c.objective);
  for (const optimize::ResponseSettings &r : c.constraints) all.push_back(&r);
  return all;
}
} // namespace

Case condition_case(const Case &c, std::size_t k, const std::vector<std::size_t> &responses) {
  Case out = c;
  if (!c.scenarios.empty()) {
    out.scene = c.scenarios.at(k).scene;
    out.time = c.scenarios.at(k).time;
    out.adjoint.file_tag = c.scenarios.at(k).name;
  }
  if (!c.load_cases.empty()) out.loads = c.load_cases.at(k).loads;
  out.scenarios.clear();
  out.load_cases.clear();
  const auto all = all_responses(c);
  if (all.empty()) return out;
  out.objective = *all.at(responses.at(0));
  out.constraints.clear();
  out.optimizer.bounds.clear();
  for (std::size_t j = 1; j < responses.size(); ++j) {
    out.constraints.push_back(*all.at(responses[j]));
    out.optimizer.bounds.push_back(all.at(responses[j])->max);
  }
  return out;
}

std::vector<std::size_t> condition_responses(const Case &c, std::size_t k) {
  std::vector<std::size_t> out;
  const auto all = all_responses(c);
  for (std::size_t i = 0; i < all.size(); ++i)
    if (std::find(all[i]->scenarios.begin(), all[i]->scenarios.end(), k) != all[i]->scenarios.end())
      out.push_back(i);
  return out;
}

optimize::ScenarioSettings scenario_settings(const Case &c) {
  optimize::ScenarioSettings s;
  s.names = condition_names(c);
  s.noun = condition_noun(c);
  const auto all = all_responses(c);
  for (std::size_t i = 0; i < all.size(); ++i) {
    s.response_names.push_back(
        (i == 0 ? std::string("objective") : "constraint" + std::to_string(i - 1)) + ":" +
        optimize::response_type_name(all[i]->type));
    s.responses.push_back(optimize::ScenarioUse{all[i]->scenarios, all[i]->combine, all[i]->weights,
                                                all[i]->combine_ks});
  }
  return s;
}

} // namespace flexopt::io
