/// \file case.yaml's scene (docs/case-format.md): materials, bodies, ground, joints, drivers,
/// interface forces and sensors.
#include "case_sections.hpp"

#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace flexopt::io::detail {

using dynamics::BodyModel;
using dynamics::JointType;
using dynamics::SensorQuantity;

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
namespace {

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

/// `bodies[].reduction` (ffrf's model settings, and the frame that acf uses too; each key given
/// recorded in b.settings as reduction.KEY) into b.reduction.
void read_reduction(const Reader &r, const YAML::Node &m, const std::string &mp,
                    dynamics::BodyDescription &b) {
  r.require_map(m, mp);
  r.check_keys(m, mp, {"modes", "geometric_stiffening", "frame"});
  for (const char *key : {"modes", "geometric_stiffening", "frame"})
    if (m[key]) b.settings.push_back(std::string("reduction.") + key);
  if (m["modes"]) {
    b.reduction.modes = r.integer(m["modes"], mp + ".modes");
    if (b.reduction.modes < 0 || b.reduction.modes > 100)
      r.fail(m["modes"], mp + ".modes: the number of fixed-interface modes must be in [0, 100]");
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

/// `bodies[].damping` (the Rayleigh [a, b] of ffrf and acf, recorded in b.settings) into
/// b.rayleigh.
void read_damping(const Reader &r, const YAML::Node &m, const std::string &mp,
                  dynamics::BodyDescription &b) {
  b.settings.push_back("damping");
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

/// `bodies[].mesh` (the meshing of a .geo geometry, extension `ext`) into b.mesh.
void read_mesh(const Reader &r, const YAML::Node &v, const std::string &path,
               const std::string &ext, dynamics::BodyDescription &b) {
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

/// `bodies[].geometry` (a .geo or .msh file relative to the case directory `dir`) and
/// `bodies[].mesh` into b.mesh.
void read_geometry(const Reader &r, const YAML::Node &v, const std::string &path,
                   const fs::path &dir, dynamics::BodyDescription &b) {
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
  if (v["mesh"]) read_mesh(r, v, path, ext, b);
}

/// `bodies[].material` (a name of `materials:`) into b.material_name and b.material.
void read_body_material(const Reader &r, const YAML::Node &v, const std::string &path,
                        const Case &c, dynamics::BodyDescription &b) {
  b.material_name = r.string(r.require(v, "material", path), path + ".material");
  const auto mat = std::find_if(c.materials.begin(), c.materials.end(),
                                [&](const MaterialSpec &m) { return m.name == b.material_name; });
  if (mat == c.materials.end())
    r.fail(v["material"], path + ".material: no material named '" + b.material_name + "'");
  b.material = fem::IsotropicMaterial{mat->E, mat->nu, mat->density};
}

/// `bodies[].interfaces` into b.interfaces, and the reduction's frame that depends on them.
void read_interfaces(const Reader &r, const YAML::Node &v, const std::string &path,
                     dynamics::BodyDescription &b) {
  if (v["interfaces"]) {
    b.interfaces = r.string_list(v["interfaces"], path + ".interfaces");
    for (std::size_t k = 0; k < b.interfaces.size(); ++k)
      if (std::count(b.interfaces.begin(), b.interfaces.begin() + static_cast<std::ptrdiff_t>(k),
                     b.interfaces[k]) > 0)
        r.fail(v["interfaces"][k], path + ".interfaces: '" + b.interfaces[k] + "' is listed twice");
  }
  // The default frame: the chord for a link between joints (docs/case-format.md).
  if (!b.reduction.frame_given)
    b.reduction.frame = b.interfaces.size() >= 2 && !b.reduction.geometric_stiffening
                            ? reduce::FrameCondition::Chord
                            : reduce::FrameCondition::Clamped;
  if (b.reduction.frame == reduce::FrameCondition::Chord && b.interfaces.size() < 2)
    r.fail(v["reduction"]["frame"], path + ".reduction.frame: chord needs two interfaces (the "
                                           "frame axis runs from the first to the second)");
}

/// One body of `bodies:` at `path` (its name unique among the bodies read before it).
dynamics::BodyDescription read_body(const Reader &r, const YAML::Node &v, const std::string &path,
                                    const fs::path &dir, const Case &c) {
  const bool dynamic = c.dynamic();
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
  if (v["reduction"]) read_reduction(r, v["reduction"], path + ".reduction", b);
  if (v["damping"]) read_damping(r, v["damping"], path + ".damping", b);
  read_geometry(r, v, path, dir, b);
  read_body_material(r, v, path, c, b);
  read_interfaces(r, v, path, b);
  if (v["initial"]) {
    if (!dynamic)
      r.fail(r.key_node(v, "initial"),
             path + ".initial: needs analysis: dynamic (a static analysis does not place or "
                    "move bodies)");
    read_initial(r, v["initial"], path + ".initial", b);
  }
  return b;
}

} // namespace

void read_bodies(const Reader &r, const YAML::Node &node, const fs::path &dir, Case &c) {
  r.require_sequence(node, "bodies");
  if (node.size() == 0) r.fail(node, "bodies: at least one body is required");
  for (std::size_t i = 0; i < node.size(); ++i)
    c.scene.bodies.push_back(read_body(r, node[i], "bodies[" + std::to_string(i) + "]", dir, c));
}

bool has_body(const Case &c, const std::string &name) {
  return std::any_of(c.scene.bodies.begin(), c.scene.bodies.end(),
                     [&](const dynamics::BodyDescription &b) { return b.name == name; });
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
namespace {

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

} // namespace

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

void read_drivers(const Reader &r, const YAML::Node &node, Case &c, const std::string &key) {
  r.require_sequence(node, key);
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node &v = node[i];
    const std::string path = key + "[" + std::to_string(i) + "]";
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
        r.fail(v["joint"], path + ".joint: joint '" + d.joint + "' already has a driver (" + key +
                               "[" + std::to_string(k) + "])");
    d.expression = r.expression(r.require(v, "value", path), path + ".value");
    c.scene.drivers.push_back(d);
  }
}

void read_forces(const Reader &r, const YAML::Node &node, Case &c, const std::string &key) {
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

} // namespace flexopt::io::detail
