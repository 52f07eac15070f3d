#include "flexopt/io/case.hpp"

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
      {"reduction", {BodyModel::Ffrf}},
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

using dynamics::BodyModel;
using dynamics::JointType;
using dynamics::SensorQuantity;

/// Keys of CASE_FORMAT.md that belong to later stages (dynamic optimization): recognised so that
/// the message says they are not available yet rather than "unknown".
const std::set<std::string> kNotYetSupported = {};

/// Top-level keys that only a dynamic analysis takes.
const char *const kDynamicOnly[] = {"ground", "joints", "drivers", "time", "accuracy"};

/// Top-level keys of the static analysis that a dynamic analysis does not take.
const char *const kStaticOnly[] = {"supports", "tractions", "line_loads"};

/// Validating reader over one YAML document: every failure names file, line and column.
class Reader {
public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  Location where(const YAML::Node &n) const {
    const YAML::Mark m = n.Mark();
    return Location{file_, m.line + 1, m.column + 1};
  }

  [[noreturn]] void fail(const YAML::Node &n, const std::string &message) const {
    throw Error(where(n).str() + ": " + message, true);
  }

  void require_map(const YAML::Node &n, const std::string &path) const {
    if (!n.IsMap()) fail(n, path + ": expected a mapping ({key: value, ...})");
  }

  void require_sequence(const YAML::Node &n, const std::string &path) const {
    if (!n.IsSequence()) fail(n, path + ": expected a list ([...] or '- ' items)");
  }

  /// Rejects keys outside `allowed`.
  void check_keys(const YAML::Node &n, const std::string &path,
                  std::initializer_list<const char *> allowed) const {
    for (const auto &kv : n) {
      const std::string key = kv.first.as<std::string>();
      bool ok =
          std::any_of(allowed.begin(), allowed.end(), [&](const char *a) { return key == a; });
      if (!ok) {
        std::string list;
        for (const char *a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
        fail(kv.first, "unknown key '" + (path.empty() ? key : path + "." + key) +
                           "' (allowed here: " + list + ")");
      }
    }
  }

  YAML::Node require(const YAML::Node &parent, const char *key, const std::string &path) const {
    YAML::Node n = parent[key];
    if (!n) fail(parent, "missing required key '" + (path.empty() ? "" : path + ".") + key + "'");
    return n;
  }

  double number(const YAML::Node &n, const std::string &path) const {
    if (!n.IsScalar()) fail(n, path + ": expected a number");
    try {
      double v = n.as<double>();
      if (!std::isfinite(v)) fail(n, path + ": expected a finite number");
      return v;
    } catch (const YAML::BadConversion &) {
      fail(n, path + ": expected a number, got '" + n.Scalar() + "'");
    }
  }

  int integer(const YAML::Node &n, const std::string &path) const {
    double v = number(n, path);
    if (v != std::floor(v) || std::abs(v) > 1e9) fail(n, path + ": expected an integer");
    return static_cast<int>(v);
  }

  bool boolean(const YAML::Node &n, const std::string &path) const {
    if (!n.IsScalar()) fail(n, path + ": expected true or false");
    try {
      return n.as<bool>();
    } catch (const YAML::BadConversion &) {
      fail(n, path + ": expected true or false, got '" + n.Scalar() + "'");
    }
  }

  std::string string(const YAML::Node &n, const std::string &path) const {
    if (!n.IsScalar()) fail(n, path + ": expected a string");
    return n.Scalar();
  }

  std::string choice(const YAML::Node &n, const std::string &path,
                     std::initializer_list<const char *> options) const {
    std::string s = string(n, path);
    for (const char *o : options)
      if (s == o) return s;
    std::string list;
    for (const char *o : options) list += std::string(list.empty() ? "" : " | ") + o;
    fail(n, path + ": '" + s + "' is not one of " + list);
  }

  /// The enumerator a name stands for (names and enumerators in `options`, in order).
  template <class E>
  E enumerated(const YAML::Node &n, const std::string &path,
               std::initializer_list<std::pair<const char *, E>> options) const {
    const std::string s = string(n, path);
    for (const auto &o : options)
      if (s == o.first) return o.second;
    std::string list;
    for (const auto &o : options) list += std::string(list.empty() ? "" : " | ") + o.first;
    fail(n, path + ": '" + s + "' is not one of " + list);
  }

  std::array<double, 3> vector3(const YAML::Node &n, const std::string &path) const {
    if (!n.IsSequence() || n.size() != 3)
      fail(n, path + ": expected a list of 3 numbers [x, y, z]");
    return {number(n[0], path + "[0]"), number(n[1], path + "[1]"), number(n[2], path + "[2]")};
  }

  /// A nonzero 3-vector, normalized.
  std::array<double, 3> direction(const YAML::Node &n, const std::string &path) const {
    std::array<double, 3> d = vector3(n, path);
    const double norm = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(norm > 0)) fail(n, path + ": must not be zero");
    for (double &x : d) x /= norm;
    return d;
  }

  /// A number or a muParser expression in t (docs/case-format.md, "Expressions"), compiled to
  /// check it; returns the text as written.
  std::string expression(const YAML::Node &n, const std::string &path) const {
    if (!n.IsScalar()) fail(n, path + ": expected a number or an expression in t (a string)");
    try {
      const Expression compiled(n.Scalar());
    } catch (const ExpressionError &e) {
      fail(n, path + ": " + e.what());
    }
    return n.Scalar();
  }

  /// A list of three numbers or muParser expressions in x, y, z (a vector field over a body),
  /// each compiled to check it; returns the texts as written.
  std::array<std::string, 3> point_field(const YAML::Node &n, const std::string &path) const {
    if (!n.IsSequence() || n.size() != 3)
      fail(n, path + ": expected [fx, fy, fz]: three numbers or expressions in x, y, z");
    std::array<std::string, 3> out;
    for (std::size_t k = 0; k < 3; ++k) {
      const std::string p = path + "[" + std::to_string(k) + "]";
      if (!n[k].IsScalar()) fail(n[k], p + ": expected a number or an expression in x, y, z");
      try {
        const PointExpression compiled(n[k].Scalar());
      } catch (const ExpressionError &e) {
        fail(n[k], p + ": " + e.what());
      }
      out[k] = n[k].Scalar();
    }
    return out;
  }

  /// The key node (not the value) of `key` in the mapping `map`, for messages about the key.
  YAML::Node key_node(const YAML::Node &map, const std::string &key) const {
    for (const auto &kv : map)
      if (kv.first.as<std::string>() == key) return kv.first;
    return map;
  }

  std::vector<std::string> string_list(const YAML::Node &n, const std::string &path) const {
    require_sequence(n, path);
    std::vector<std::string> out;
    for (std::size_t i = 0; i < n.size(); ++i)
      out.push_back(string(n[i], path + "[" + std::to_string(i) + "]"));
    return out;
  }

private:
  std::string file_;
};

void read_materials(const Reader &r, const YAML::Node &node, Case &c) {
  r.require_map(node, "materials");
  for (const auto &kv : node) {
    MaterialSpec m;
    m.name = kv.first.as<std::string>();
    const std::string path = "materials." + m.name;
    const YAML::Node &v = kv.second;
    r.require_map(v, path);
    r.check_keys(v, path, {"E", "nu", "density"});
    m.E = r.number(r.require(v, "E", path), path + ".E");
    m.nu = r.number(r.require(v, "nu", path), path + ".nu");
    m.density = r.number(r.require(v, "density", path), path + ".density");
    if (!(m.E > 0)) r.fail(v["E"], path + ".E: Young's modulus must be positive");
    if (!(m.nu > -1.0 && m.nu < 0.5))
      r.fail(v["nu"], path + ".nu: Poisson's ratio must satisfy -1 < nu < 0.5 (got " +
                          v["nu"].Scalar() +
                          "; nu = 0.5 is incompressible, which the displacement "
                          "formulation cannot represent)");
    if (!(m.density > 0)) r.fail(v["density"], path + ".density: must be positive");
    c.materials.push_back(m);
  }
  if (c.materials.empty()) r.fail(node, "materials: at least one material is required");
}

/// "a, b, c", or `none` for an empty list.
std::string join(const std::vector<std::string> &names, const char *none = "none") {
  std::string out;
  for (const auto &n : names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? none : out;
}

/// Reads `bodies[].initial` into `b.initial`; the elastic fields (model settings) are recorded
/// in `b.settings`.
void read_initial(const Reader &r, const YAML::Node &v, const std::string &path,
                  dynamics::BodyDescription &b) {
  dynamics::InitialPlacement &s = b.initial;
  r.require_map(v, path);
  r.check_keys(v, path,
               {"position", "rotation", "velocity", "angular_velocity", "elastic_displacement",
                "elastic_velocity"});
  if (v["position"]) s.position = r.vector3(v["position"], path + ".position");
  if (v["rotation"]) {
    const YAML::Node &rot = v["rotation"];
    const std::string rp = path + ".rotation";
    r.require_map(rot, rp);
    r.check_keys(rot, rp, {"axis", "angle"});
    s.axis = r.direction(r.require(rot, "axis", rp), rp + ".axis");
    s.angle = r.number(r.require(rot, "angle", rp), rp + ".angle");
  }
  if (v["velocity"]) s.velocity = r.vector3(v["velocity"], path + ".velocity");
  if (v["angular_velocity"])
    s.angular_velocity = r.vector3(v["angular_velocity"], path + ".angular_velocity");
  for (const char *key : {"elastic_displacement", "elastic_velocity"}) {
    if (!v[key]) continue;
    b.settings.push_back(std::string("initial.") + key);
    (std::string(key) == "elastic_velocity" ? s.elastic_velocity : s.elastic_displacement) =
        r.point_field(v[key], path + "." + key);
  }
}

void read_bodies(const Reader &r, const YAML::Node &node, const fs::path &dir, Case &c) {
  const bool dynamic = c.dynamic();
  r.require_sequence(node, "bodies");
  if (node.size() == 0) r.fail(node, "bodies: at least one body is required");
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = "bodies[" + std::to_string(i) + "]";
    r.require_map(v, path);
    r.check_keys(v, path,
                 {"name", "model", "geometry", "mesh", "material", "interfaces", "reduction",
                  "damping", "initial"});
    dynamics::BodyDescription b;
    b.where = r.where(v);
    b.name = r.string(r.require(v, "name", path), path + ".name");
    if (b.name == "ground")
      r.fail(v["name"], path + ".name: 'ground' is reserved for the fixed frame (joints name it as "
                               "a or b); choose another body name");
    for (const auto &other : c.scene.bodies)
      if (other.name == b.name)
        r.fail(v["name"], path + ".name: duplicate body name '" + b.name + "'");
    if (v["model"])
      b.model = r.enumerated(v["model"], path + ".model",
                             {std::pair{"rigid", BodyModel::Rigid},
                              {"ffrf", BodyModel::Ffrf},
                              {"acf", BodyModel::Acf},
                              {"auto", BodyModel::Auto}});
    // The settings of every model are read and checked whatever `model` is (a body may carry
    // them all; `model` picks the ones used, and unused_settings() reports the others).
    if (v["reduction"]) {
      b.settings.push_back("reduction");
      const YAML::Node &m = v["reduction"];
      const std::string mp = path + ".reduction";
      r.require_map(m, mp);
      r.check_keys(m, mp, {"modes", "geometric_stiffening", "frame"});
      if (m["modes"]) {
        b.reduction.modes = r.integer(m["modes"], mp + ".modes");
        if (b.reduction.modes < 0 || b.reduction.modes > 100)
          r.fail(m["modes"],
                 mp + ".modes: the number of fixed-interface modes must be in [0, 100]");
      }
      if (m["geometric_stiffening"])
        b.reduction.geometric_stiffening =
            r.boolean(m["geometric_stiffening"], mp + ".geometric_stiffening");
      if (m["frame"]) {
        b.reduction.frame = r.enumerated(m["frame"], mp + ".frame",
                                         {std::pair{"clamped", reduce::FrameCondition::Clamped},
                                          {"chord", reduce::FrameCondition::Chord}});
        b.reduction.frame_given = true;
        if (b.reduction.frame == reduce::FrameCondition::Chord && b.reduction.geometric_stiffening)
          r.fail(m["frame"], mp + ".frame: chord does not combine with geometric_stiffening (the "
                                  "centrifugal preload is the stress of the body clamped at its "
                                  "first interface)");
      }
    }
    if (v["damping"]) {
      b.settings.push_back("damping");
      const YAML::Node &m = v["damping"];
      const std::string mp = path + ".damping";
      r.require_map(m, mp);
      r.check_keys(m, mp, {"rayleigh"});
      const YAML::Node &ray = r.require(m, "rayleigh", mp);
      if (!ray.IsSequence() || ray.size() != 2)
        r.fail(ray, mp + ".rayleigh: expected [a, b] (C = a M + b K)");
      for (std::size_t k = 0; k < 2; ++k) {
        b.rayleigh[k] = r.number(ray[k], mp + ".rayleigh[" + std::to_string(k) + "]");
        if (b.rayleigh[k] < 0)
          r.fail(ray[k], mp + ".rayleigh[" + std::to_string(k) + "]: must not be negative");
      }
      // Only where acf uses it: the same [a, b] serves an ffrf body.
      if (dynamics::simulated_model(b.model) == BodyModel::Acf && b.rayleigh[0] != 0)
        r.fail(ray[0], mp + ".rayleigh[0]: an acf body takes stiffness-proportional damping "
                            "only, [0, b]: mass-proportional damping of its absolute velocities "
                            "would brake its rigid motion (docs/theory.md section 8.1; an ffrf "
                            "body takes [a, b])");
    }
    b.mesh.where = b.mesh.body_where = b.where;
    b.mesh.body = b.name;
    b.mesh.geometry_key = r.string(r.require(v, "geometry", path), path + ".geometry");
    b.mesh.geometry = (dir / b.mesh.geometry_key).string();
    const std::string ext = fs::path(b.mesh.geometry).extension().string();
    if (ext != ".geo" && ext != ".msh")
      r.fail(v["geometry"], path + ".geometry: '" + b.mesh.geometry_key +
                                "' must be a Gmsh .geo (meshed at run time) or .msh (v4) file");
    if (!fs::is_regular_file(b.mesh.geometry))
      r.fail(v["geometry"], path + ".geometry: file '" + b.mesh.geometry + "' does not exist");
    if (v["mesh"]) {
      const YAML::Node &m = v["mesh"];
      const std::string mp = path + ".mesh";
      r.require_map(m, mp);
      r.check_keys(m, mp, {"size", "order", "max_elements"});
      b.mesh.given = true;
      b.mesh.where = r.where(r.key_node(v, "mesh"));
      if (ext == ".msh")
        r.fail(m, mp + ": only applies to a .geo geometry; a .msh file is used as it is");
      if (m["size"]) {
        b.mesh.size = r.number(m["size"], mp + ".size");
        if (!(b.mesh.size > 0)) r.fail(m["size"], mp + ".size: element size must be positive");
      }
      if (m["order"]) {
        b.mesh.order = r.integer(m["order"], mp + ".order");
        if (b.mesh.order != 1 && b.mesh.order != 2)
          r.fail(m["order"], mp + ".order: must be 1 (Tet4/Hex8) or 2 (Tet10)");
      }
      if (m["max_elements"]) {
        b.mesh.max_elements = r.integer(m["max_elements"], mp + ".max_elements");
        if (b.mesh.max_elements < 1)
          r.fail(m["max_elements"], mp + ".max_elements: must be a positive integer");
      }
    }
    b.material_name = r.string(r.require(v, "material", path), path + ".material");
    const auto mat = std::find_if(c.materials.begin(), c.materials.end(),
                                  [&](const MaterialSpec &m) { return m.name == b.material_name; });
    if (mat == c.materials.end())
      r.fail(v["material"], path + ".material: no material named '" + b.material_name + "'");
    b.material = fem::IsotropicMaterial{mat->E, mat->nu, mat->density};
    if (v["interfaces"]) {
      b.interfaces = r.string_list(v["interfaces"], path + ".interfaces");
      for (std::size_t k = 0; k < b.interfaces.size(); ++k)
        if (std::count(b.interfaces.begin(), b.interfaces.begin() + static_cast<std::ptrdiff_t>(k),
                       b.interfaces[k]) > 0)
          r.fail(v["interfaces"][k],
                 path + ".interfaces: '" + b.interfaces[k] + "' is listed twice");
    }
    // The default frame: the chord for a link between joints (docs/case-format.md).
    if (!b.reduction.frame_given)
      b.reduction.frame = b.interfaces.size() >= 2 && !b.reduction.geometric_stiffening
                              ? reduce::FrameCondition::Chord
                              : reduce::FrameCondition::Clamped;
    if (b.reduction.frame == reduce::FrameCondition::Chord && b.interfaces.size() < 2)
      r.fail(v["reduction"]["frame"], path + ".reduction.frame: chord needs two interfaces (the "
                                             "frame axis runs from the first to the second)");
    if (v["initial"]) {
      if (!dynamic)
        r.fail(r.key_node(v, "initial"),
               path + ".initial: needs analysis: dynamic (a static analysis does not place or "
                      "move bodies)");
      read_initial(r, v["initial"], path + ".initial", b);
    }
    c.scene.bodies.push_back(b);
  }
}

bool has_body(const Case &c, const std::string &name) {
  return std::any_of(c.scene.bodies.begin(), c.scene.bodies.end(),
                     [&](const dynamics::BodyDescription &b) { return b.name == name; });
}

void read_supports(const Reader &r, const YAML::Node &node, Case &c) {
  r.require_sequence(node, "supports");
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = "supports[" + std::to_string(i) + "]";
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

void read_tractions(const Reader &r, const YAML::Node &node, Case &c, const char *key,
                    const char *where_key, std::vector<fem::SurfaceLoad> &out) {
  r.require_sequence(node, key);
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = std::string(key) + "[" + std::to_string(i) + "]";
    r.require_map(v, path);
    const bool surface = std::string(where_key) == "surface";
    if (surface)
      r.check_keys(v, path, {"body", where_key, "value", "force"});
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
    } else {
      t.value = r.vector3(r.require(v, "value", path), path + ".value");
    }
    out.push_back(t);
  }
}

void read_ground(const Reader &r, const YAML::Node &node, Case &c) {
  r.require_map(node, "ground");
  r.check_keys(node, "ground", {"interfaces"});
  const YAML::Node &l = r.require(node, "interfaces", "ground");
  r.require_map(l, "ground.interfaces");
  for (const auto &kv : l) {
    dynamics::GroundInterface g;
    g.name = r.string(kv.first, "ground.interfaces");
    g.where = r.where(kv.first);
    const std::string path = "ground.interfaces." + g.name;
    for (const auto &other : c.scene.ground)
      if (other.name == g.name) r.fail(kv.first, path + ": duplicate ground interface name");
    g.origin = r.vector3(kv.second, path);
    c.scene.ground.push_back(g);
  }
  if (c.scene.ground.empty())
    r.fail(l, "ground.interfaces: name at least one point (NAME: [x, y, z])");
}

/// Checks that `side` ("a" or "b") of a joint names ground or a body, and that its interface
/// is one of that body's `interfaces:` (or a ground interface).
void check_joint_side(const Reader &r, const YAML::Node &v, const std::string &path,
                      const dynamics::JointDescription &j, const char *side, const Case &c) {
  const std::string &who = side[0] == 'a' ? j.a : j.b;
  const std::string &iface = side[0] == 'a' ? j.a_interface : j.b_interface;
  const std::string ikey = std::string(side) + "_interface";
  const std::string head = "joint '" + j.name + "': ";
  if (who == "ground") {
    std::vector<std::string> names;
    for (const auto &g : c.scene.ground) names.push_back(g.name);
    if (std::find(names.begin(), names.end(), iface) != names.end()) return;
    if (names.empty())
      r.fail(v[ikey], path + "." + ikey + ": " + head + "ground has no interface '" + iface +
                          "' (there is no ground: section; add ground: {interfaces: {" + iface +
                          ": [x, y, z]}})");
    r.fail(v[ikey], path + "." + ikey + ": " + head + "ground has no interface '" + iface +
                        "' (ground interfaces: " + join(names) + ")");
  }
  const dynamics::BodyDescription *body = nullptr;
  std::vector<std::string> bodies;
  for (const auto &b : c.scene.bodies) {
    bodies.push_back(b.name);
    if (b.name == who) body = &b;
  }
  if (!body)
    r.fail(v[side], path + "." + side + ": " + head + "no body named '" + who +
                        "' (bodies: " + join(bodies) + "; or ground)");
  if (std::find(body->interfaces.begin(), body->interfaces.end(), iface) != body->interfaces.end())
    return;
  if (body->interfaces.empty())
    r.fail(v[ikey], path + "." + ikey + ": " + head + "body '" + who + "' has no interface '" +
                        iface + "' (it lists none; add interfaces: [" + iface +
                        "] to the body, a physical surface of its geometry)");
  r.fail(v[ikey], path + "." + ikey + ": " + head + "body '" + who + "' has no interface '" +
                      iface + "' (its interfaces: " + join(body->interfaces) + ")");
}

void read_joints(const Reader &r, const YAML::Node &node, Case &c) {
  r.require_sequence(node, "joints");
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = "joints[" + std::to_string(i) + "]";
    r.require_map(v, path);
    r.check_keys(v, path, {"name", "type", "a", "a_interface", "b", "b_interface", "axis"});
    dynamics::JointDescription j;
    j.where = r.where(v);
    j.name = r.string(r.require(v, "name", path), path + ".name");
    for (const auto &other : c.scene.joints)
      if (other.name == j.name)
        r.fail(v["name"], path + ".name: duplicate joint name '" + j.name + "'");
    j.type = r.enumerated(r.require(v, "type", path), path + ".type",
                          {std::pair{"revolute", JointType::Revolute},
                           {"spherical", JointType::Spherical},
                           {"prismatic", JointType::Prismatic},
                           {"fixed", JointType::Fixed}});
    const std::string type = dynamics::joint_type_name(j.type);
    j.a = r.string(r.require(v, "a", path), path + ".a");
    j.a_interface = r.string(r.require(v, "a_interface", path), path + ".a_interface");
    j.b = r.string(r.require(v, "b", path), path + ".b");
    j.b_interface = r.string(r.require(v, "b_interface", path), path + ".b_interface");
    check_joint_side(r, v, path, j, "a", c);
    check_joint_side(r, v, path, j, "b", c);
    if (j.a == "ground" && j.b == "ground")
      r.fail(v["b"], path + ".b: joint '" + j.name + "': a and b are both ground");
    if (j.a == j.b)
      r.fail(v["b"], path + ".b: joint '" + j.name + "': a and b are the same body '" + j.a +
                         "' (a joint connects two bodies, or a body and ground)");
    const bool has_axis = j.type == JointType::Revolute || j.type == JointType::Prismatic;
    if (has_axis) {
      if (!v["axis"])
        r.fail(v, path + ": joint '" + j.name + "': a " + type +
                      " joint needs axis: [x, y, z] (world frame, t = 0)");
      j.axis = r.direction(v["axis"], path + ".axis");
    } else if (v["axis"]) {
      r.fail(v["axis"], path + ".axis: a " + type + " joint has no axis");
    }
    c.scene.joints.push_back(j);
  }
}

void read_drivers(const Reader &r, const YAML::Node &node, Case &c) {
  r.require_sequence(node, "drivers");
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = "drivers[" + std::to_string(i) + "]";
    r.require_map(v, path);
    r.check_keys(v, path, {"joint", "value"});
    dynamics::DriverDescription d;
    d.where = r.where(v);
    d.joint = r.string(r.require(v, "joint", path), path + ".joint");
    const dynamics::JointDescription *joint = nullptr;
    std::vector<std::string> names;
    for (const auto &j : c.scene.joints) {
      names.push_back(j.name);
      if (j.name == d.joint) joint = &j;
    }
    if (!joint)
      r.fail(v["joint"],
             path + ".joint: no joint named '" + d.joint + "' (joints: " + join(names) + ")");
    if (joint->type != JointType::Revolute && joint->type != JointType::Prismatic)
      r.fail(v["joint"], path + ".joint: joint '" + d.joint + "' is " +
                             dynamics::joint_type_name(joint->type) +
                             "; a driver prescribes the coordinate of a revolute or prismatic "
                             "joint");
    for (std::size_t k = 0; k < c.scene.drivers.size(); ++k)
      if (c.scene.drivers[k].joint == d.joint)
        r.fail(v["joint"], path + ".joint: joint '" + d.joint + "' already has a driver (drivers[" +
                               std::to_string(k) + "])");
    d.expression = r.expression(r.require(v, "value", path), path + ".value");
    c.scene.drivers.push_back(d);
  }
}

void read_forces(const Reader &r, const YAML::Node &node, Case &c) {
  const std::string key = "loads.forces";
  r.require_sequence(node, key);
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = key + "[" + std::to_string(i) + "]";
    r.require_map(v, path);
    r.check_keys(v, path, {"body", "interface", "value"});
    dynamics::ForceDescription f;
    f.where = r.where(v);
    f.body = r.string(r.require(v, "body", path), path + ".body");
    if (f.body == "ground")
      r.fail(v["body"], path + ".body: the ground is fixed; a force acts on a body");
    if (!has_body(c, f.body)) r.fail(v["body"], path + ".body: no body named '" + f.body + "'");
    const dynamics::BodyDescription &b = c.scene.body(f.body);
    f.interface = r.string(r.require(v, "interface", path), path + ".interface");
    if (std::find(b.interfaces.begin(), b.interfaces.end(), f.interface) == b.interfaces.end())
      r.fail(v["interface"], path + ".interface: body '" + f.body + "' has no interface '" +
                                 f.interface + "' (its interfaces: " + join(b.interfaces) + ")");
    const YAML::Node &val = r.require(v, "value", path);
    if (!val.IsSequence() || val.size() != 3)
      r.fail(val, path + ".value: expected a list of 3 components [x, y, z], each a number or an "
                         "expression in t");
    for (std::size_t k = 0; k < 3; ++k)
      f.value[k] = r.expression(val[k], path + ".value[" + std::to_string(k) + "]");
    c.scene.forces.push_back(f);
  }
}

void read_time(const Reader &r, const YAML::Node &v, Case &c) {
  const std::string path = "time";
  r.require_map(v, path);
  r.check_keys(v, path, {"end", "step", "rho_inf", "newton_reuse"});
  dynamics::TimeSettings &t = c.time;
  t.where = r.where(v);
  t.end = r.number(r.require(v, "end", path), path + ".end");
  if (!(t.end > 0)) r.fail(v["end"], path + ".end: must be positive");
  t.step = r.number(r.require(v, "step", path), path + ".step");
  if (!(t.step > 0)) r.fail(v["step"], path + ".step: must be positive");
  if (!(t.step <= t.end))
    r.fail(v["step"], path + ".step: must not exceed time.end (" + v["end"].Scalar() + ")");
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

void read_sensors(const Reader &r, const YAML::Node &node, Case &c) {
  r.require_sequence(node, "sensors");
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = "sensors[" + std::to_string(i) + "]";
    r.require_map(v, path);
    r.check_keys(v, path, {"name", "body", "point", "quantity", "joint"});
    dynamics::SensorDescription s;
    s.where = r.where(v);
    s.name = r.string(r.require(v, "name", path), path + ".name");
    for (const auto &other : c.scene.sensors)
      if (other.name == s.name)
        r.fail(v["name"], path + ".name: duplicate sensor name '" + s.name + "'");
    if (v["joint"]) {
      // A joint sensor: the reaction force of a joint with a coincident point.
      for (const char *k : {"body", "point"})
        if (v[k])
          r.fail(v[k], path + "." + k +
                           ": a joint sensor measures the joint's reaction and "
                           "takes no " +
                           k);
      s.joint = r.string(v["joint"], path + ".joint");
      const dynamics::JointDescription *joint = nullptr;
      for (const auto &j : c.scene.joints)
        if (j.name == s.joint) joint = &j;
      if (!joint) r.fail(v["joint"], path + ".joint: no joint named '" + s.joint + "'");
      if (joint->type == JointType::Prismatic)
        r.fail(v["joint"], path + ".joint: joint '" + s.joint +
                               "' is prismatic; reaction sensors measure the force at the "
                               "coincident point of a revolute, spherical or fixed joint");
      s.quantity = SensorQuantity::Reaction;
      if (v["quantity"]) r.choice(v["quantity"], path + ".quantity", {"reaction"});
      c.scene.sensors.push_back(s);
      continue;
    }
    s.body = r.string(r.require(v, "body", path), path + ".body");
    if (!has_body(c, s.body)) r.fail(v["body"], path + ".body: no body named '" + s.body + "'");
    s.point = r.vector3(r.require(v, "point", path), path + ".point");
    if (v["quantity"]) {
      const YAML::Node &q = v["quantity"];
      s.quantity = r.enumerated(q, path + ".quantity",
                                {std::pair{"displacement", SensorQuantity::Displacement},
                                 {"position", SensorQuantity::Position},
                                 {"elastic_displacement", SensorQuantity::ElasticDisplacement},
                                 {"rotation_angle", SensorQuantity::RotationAngle}});
      // ("reaction" belongs to joint sensors: `joint:` instead of `body:` and `point:`.)
      if (!c.dynamic() && s.quantity != SensorQuantity::Displacement &&
          s.quantity != SensorQuantity::Position)
        r.fail(q, path + ".quantity: '" + std::string(dynamics::quantity_name(s.quantity)) +
                      "' needs a dynamic analysis; a static one has displacement and position");
    }
    c.scene.sensors.push_back(s);
  }
}

void read_design(const Reader &r, const YAML::Node &v, Case &c) {
  const std::string path = "design";
  r.require_map(v, path);
  r.check_keys(v, path, {"body", "region", "initial", "interpolation", "filter", "projection"});
  optimize::DesignSettings d;
  d.where = r.where(v);
  d.body = r.string(r.require(v, "body", path), path + ".body");
  if (!has_body(c, d.body)) r.fail(v["body"], path + ".body: no body named '" + d.body + "'");
  if (v["region"]) d.region = r.string(v["region"], path + ".region");
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
    r.check_keys(i, ip, {"penalty", "min_stiffness", "mass"});
    if (i["penalty"]) {
      d.penalty = r.number(i["penalty"], ip + ".penalty");
      if (!(d.penalty >= 1)) r.fail(i["penalty"], ip + ".penalty: the SIMP exponent must be >= 1");
    }
    if (i["min_stiffness"]) {
      d.min_stiffness = r.number(i["min_stiffness"], ip + ".min_stiffness");
      if (!(d.min_stiffness > 0 && d.min_stiffness < 1))
        r.fail(i["min_stiffness"], ip + ".min_stiffness: E_min / E_0 must lie in (0, 1)");
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
  }
  c.design = d;
}

optimize::ResponseSettings read_response(const Reader &r, const YAML::Node &v,
                                         const std::string &path, bool constraint, const Case &c) {
  using optimize::ResponseType;
  r.require_map(v, path);
  r.check_keys(
      v, path,
      {"type", "sensor", "direction", "body", "target", "component", "measure", "ks", "max"});
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
                         {"mass", ResponseType::Mass}});
  const std::string type = optimize::response_type_name(s.type);
  const bool dynamic_only = s.type == ResponseType::StrainEnergyIntegral ||
                            s.type == ResponseType::TrackingError ||
                            s.type == ResponseType::Sensor || s.type == ResponseType::Mass;
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
  if (s.type == ResponseType::StrainEnergyIntegral || s.type == ResponseType::Mass)
    takes = {"body"};
  for (const char *k : {"sensor", "direction", "body", "target", "component", "measure", "ks"})
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
    s.body = r.string(r.require(v, "body", path), path + ".body");
    if (!has_body(c, s.body)) r.fail(v["body"], path + ".body: no body named '" + s.body + "'");
  }
  if (constraint) {
    s.max = r.number(r.require(v, "max", path), path + ".max");
    s.has_max = true;
    if (s.type == ResponseType::VolumeFraction && !(s.max > 0 && s.max < 1))
      r.fail(v["max"], path + ".max: a volume fraction bound must lie in (0, 1)");
    if (s.type == ResponseType::Mass && !(s.max > 0))
      r.fail(v["max"], path + ".max: a mass bound must be positive [kg]");
  } else if (v["max"]) {
    r.fail(v["max"], path + ".max: the objective takes no bound");
  }
  return s;
}

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

} // namespace

fem::StaticSettings static_settings(const Case &c) {
  const dynamics::BodyDescription &body = c.scene.bodies.front();
  return fem::StaticSettings{body.mesh, body.material, c.loads, c.file};
}

optimize::TopologySettings topology_settings(const Case &c) {
  if (!c.design || !c.objective)
    throw Error(c.file + ": topology optimization needs design: and objective: sections", true);
  return optimize::TopologySettings{static_settings(c), *c.design, *c.objective, c.constraints};
}

adjoint::DynamicSettings dynamic_settings(const Case &c) {
  if (!c.design || !c.objective)
    throw Error(c.file + ": an optimization needs design: and objective: sections", true);
  return adjoint::DynamicSettings{c.scene,      c.time,        *c.design,
                                  *c.objective, c.constraints, c.adjoint};
}

plan::PlanSettings plan_settings(const Case &c) {
  plan::PlanSettings s{c.scene, c.time, c.accuracy, c.design ? c.design->body : "", {}};
  std::vector<const optimize::ResponseSettings *> responses;
  if (c.objective) responses.push_back(&*c.objective);
  for (const optimize::ResponseSettings &r : c.constraints) responses.push_back(&r);
  for (const optimize::ResponseSettings *r : responses)
    if (!r->sensor.empty())
      s.sensor_responses.emplace_back(optimize::response_type_name(r->type), r->sensor);
  return s;
}

Case load_case(const std::string &directory) {
  Case c;
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
  Reader r(c.file);
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
               {"analysis", "materials", "bodies",      "ground",    "joints",  "drivers", "loads",
                "supports", "tractions", "line_loads",  "time",      "sensors", "output",  "solver",
                "design",   "objective", "constraints", "optimizer", "adjoint", "accuracy"});

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
  read_materials(r, r.require(root, "materials", ""), c);
  read_bodies(r, r.require(root, "bodies", ""), dir, c);
  if (root["ground"]) read_ground(r, root["ground"], c);
  if (root["joints"]) read_joints(r, root["joints"], c);
  if (root["drivers"]) read_drivers(r, root["drivers"], c);

  if (root["loads"]) {
    const YAML::Node &l = root["loads"];
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
      read_forces(r, l["forces"], c);
    }
  }
  if (root["time"]) read_time(r, root["time"], c);
  if (root["supports"]) read_supports(r, root["supports"], c);
  if (root["tractions"])
    read_tractions(r, root["tractions"], c, "tractions", "surface", c.loads.tractions);
  if (root["line_loads"])
    read_tractions(r, root["line_loads"], c, "line_loads", "curve", c.loads.line_loads);
  if (root["sensors"]) read_sensors(r, root["sensors"], c);
  if (root["output"]) read_output(r, root["output"], dynamic, c);
  if (root["solver"]) c.solver = r.string(root["solver"], "solver");
  if (root["accuracy"]) {
    c.accuracy = r.number(root["accuracy"], "accuracy");
    if (!(c.accuracy > 0 && c.accuracy < 1))
      r.fail(root["accuracy"], "accuracy: the accepted relative error of the sensors must lie in "
                               "(0, 1), e.g. 1e-2");
  }
  if (root["design"]) read_design(r, root["design"], c);
  if (root["objective"]) c.objective = read_response(r, root["objective"], "objective", false, c);
  if (root["constraints"]) {
    const YAML::Node &l = root["constraints"];
    r.require_sequence(l, "constraints");
    for (std::size_t i = 0; i < l.size(); ++i)
      c.constraints.push_back(
          read_response(r, l[i], "constraints[" + std::to_string(i) + "]", true, c));
  }
  if (root["optimizer"]) {
    const YAML::Node &o = root["optimizer"];
    r.require_map(o, "optimizer");
    r.check_keys(o, "optimizer", {"max_iterations", "move_limit", "tolerance"});
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
      if (!(c.optimizer.tolerance >= 0))
        r.fail(o["tolerance"], "optimizer.tolerance: must be >= 0");
    }
  }
  if (root["adjoint"]) {
    if (!dynamic)
      r.fail(r.key_node(root, "adjoint"),
             "adjoint: needs analysis: dynamic (a static optimization stores no states)");
    read_adjoint(r, root["adjoint"], c);
  }
  if ((c.objective || !c.constraints.empty() || root["optimizer"]) && !c.design)
    r.fail(root, "objective/constraints/optimizer need a design: section (the design field)");
  if (c.design && !c.objective)
    r.fail(root["design"], "design: an optimization needs an objective:");

  // The optimizer's share of other keys: the constraints' bounds, and design.xdmf's stride
  // (output.every thins it in a static analysis only: in a dynamic one it counts the motion's
  // time steps, docs/case-format.md "output").
  for (const optimize::ResponseSettings &con : c.constraints) c.optimizer.bounds.push_back(con.max);
  c.optimizer.output_every = dynamic ? 1 : std::max(c.output.every, 1);

  if (!dynamic && c.scene.bodies.size() != 1)
    r.fail(root["bodies"], "bodies: a static analysis takes exactly one body (got " +
                               std::to_string(c.scene.bodies.size()) + ")");
  if (dynamic && !c.time.given)
    r.fail(root["analysis"], "analysis: a dynamic analysis needs time: {end: T, step: h}");
  return c;
}

} // namespace flexopt::io
