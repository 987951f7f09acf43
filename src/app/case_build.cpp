// Building a case: from a case file to a ready Simulation (or, for a distributed run, what
// each process needs to build its subdomain), and the resolved case the run reports.
#include "app/case_run.hpp"
#include "parallel/comm.hpp"
#include "io/output.hpp"
#include "solver/law_kernels.hpp"
#include "material/bar_law_fatigue.hpp"
#include "solver/laws.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numbers>
#include <numeric>
#include <sstream>
#include <toml++/toml.h>
#include <variant>

namespace ldem {

namespace {

std::vector<index_t> select(const Lattice& lat, const NodeSetSpec& s) {
  switch (s.kind) {
  case NodeSetSpec::Kind::Face:
    return select_face(lat, s.face);
  case NodeSetSpec::Kind::FaceCentres:
    return select_face_module_centres(lat, s.face);
  case NodeSetSpec::Kind::Box:
    return select_box(lat, s.lo, s.hi);
  case NodeSetSpec::Kind::Shape:
    return s.surface ? select_surface(lat, s.shape) : select_shape(lat, s.shape);
  case NodeSetSpec::Kind::All:
    break;
  }
  return select_all(lat);
}

std::string how(const NodeSetSpec& s) {
  switch (s.kind) {
  case NodeSetSpec::Kind::Face:
    return "face " + face_name(s.face);
  case NodeSetSpec::Kind::FaceCentres:
    return "centres of the modules along face " + face_name(s.face);
  case NodeSetSpec::Kind::Box:
    return fmt::format("box [{:g}, {:g}, {:g}] to [{:g}, {:g}, {:g}]", s.lo.x, s.lo.y, s.lo.z,
                       s.hi.x, s.hi.y, s.hi.z);
  case NodeSetSpec::Kind::Shape:
    return (s.surface ? "the body's surface in " : "") + s.shape.describe();
  case NodeSetSpec::Kind::All:
    break;
  }
  return "all nodes";
}

// A shape as the case file gives it (the resolved case).
toml::table shape_table(const Shape& sh) {
  auto vec = [](Vec3 v) { return toml::array{v.x, v.y, v.z}; };
  switch (sh.type) {
  case Shape::Type::Box: {
    toml::table t{{"type", "box"}, {"min", vec(sh.lo)}, {"max", vec(sh.hi)}};
    if (sh.axis >= 0) {
      t.insert("axis", std::string(1, "xyz"[sh.axis]));
      t.insert("angle", sh.angle * 180.0 / std::numbers::pi);
    }
    return t;
  }
  case Shape::Type::Cylinder:
    return toml::table{
        {"type", "cylinder"}, {"start", vec(sh.a)}, {"end", vec(sh.b)}, {"radius", sh.radius}};
  case Shape::Type::Sphere:
    return toml::table{{"type", "sphere"}, {"centre", vec(sh.a)}, {"radius", sh.radius}};
  case Shape::Type::HalfSpace:
    return toml::table{{"type", "half_space"}, {"point", vec(sh.a)}, {"normal", vec(sh.normal)}};
  case Shape::Type::Mask:
    break;
  }
  if (sh.stl)
    return toml::table{{"type", "stl"}, {"file", sh.file}, {"scale", sh.scale}};
  return toml::table{{"type", "npy"}, {"file", sh.file}};
}

// A traction load's nodes weighted by the area each stands for (docs/model.md, 6); none for a
// force per node.
// Of the items [0, count) that `present` keeps, the first one whose position is nearest to
// `point` (probes: a bar's centre, a node).
template <class Present, class Position>
index_t nearest(index_t count, Vec3 point, Present present, Position position) {
  index_t best = 0;
  double d_best = INFINITY;
  for (index_t i = 0; i < count; ++i) {
    if (!present(i))
      continue;
    const Vec3 x = position(i);
    const double d = (x.x - point.x) * (x.x - point.x) + (x.y - point.y) * (x.y - point.y) +
                     (x.z - point.z) * (x.z - point.z);
    if (d < d_best) {
      d_best = d;
      best = i;
    }
  }
  return best;
}

std::vector<double> traction_weights(const CaseSpec& s, const LoadSpec& l, const Lattice& lat,
                                     const NodeSet& set) {
  if (l.kind != LoadSpec::Kind::Traction && l.kind != LoadSpec::Kind::Total)
    return {};
  const auto spec = std::find_if(s.node_sets.begin(), s.node_sets.end(),
                                 [&](const NodeSetSpec& n) { return n.name == l.set; });
  if (spec != s.node_sets.end() && spec->kind == NodeSetSpec::Kind::Face)
    return face_tributary_areas(lat, spec->face);
  if (spec != s.node_sets.end() && spec->kind == NodeSetSpec::Kind::FaceCentres)
    return std::vector<double>(select_face_module_centres(lat, spec->face).size(),
                               lat.L() * lat.L());
  std::vector<double> area = surface_tributary_areas(lat, set.nodes);
  if (std::all_of(area.begin(), area.end(), [](double a) { return a == 0.0; }))
    throw InputError(fmt::format(
        "load \"{}\" has a {}: expected a node set that covers some of the body's surface (the "
        "four corners of a module face on it), got \"{}\", {} that covers none; give force (N "
        "on each node) instead",
        l.name, l.kind == LoadSpec::Kind::Traction ? "traction" : "total", l.set,
        spec == s.node_sets.end() ? "not a node set" : how(*spec)));
  return area;
}

// A load's force per unit weight: its force, traction or acceleration as given; a total spread
// over the area.
Vec3 force_per_weight(const LoadSpec& l, const std::vector<double>& weight) {
  if (l.kind != LoadSpec::Kind::Total)
    return l.force;
  double area = 0.0;
  for (double a : weight)
    area += a;
  return {l.force.x / area, l.force.y / area, l.force.z / area};
}

} // namespace

double load_total_force(const BuiltCase& c, std::size_t i, double t) {
  // The whole body's load (c.conditions, not a subdomain's), its nodes' weights added.
  const LoadSpec& l = c.spec.loads[i];
  const NodalLoad& whole = c.conditions.loads[i];
  double weight = 0.0;
  for (std::size_t q = 0; q < whole.set.nodes.size(); ++q)
    weight += whole.weight_of(q);
  const Vec3 f = whole.force; // per unit weight (a total's: divided by the area)
  return l.scale(t) * std::sqrt(f.x * f.x + f.y * f.y + f.z * f.z) * weight;
}

namespace {

std::string dofs_text(DofMask m) {
  std::string s;
  for (int d = 0; d < 3; ++d)
    if (m & (1u << d))
      s += static_cast<char>('x' + d);
  return s;
}

// Conditions that contradict each other: two [[velocity]] tables imposing the same DOF of a
// node (each would book the reaction's work and the node's kinetic energy, and the last one's
// target would win), a DOF a [[fixed]] table holds and a [[velocity]] table drives, and a
// [[velocity]] table driving the component plane strain holds. Throws InputError naming the
// tables, their node sets, the DOF, how many nodes and the first of them. ([[fixed]] tables
// may overlap each other and plane strain: they all hold the DOF at zero.)
void check_conditions_agree(const CaseSpec& s, const std::vector<NodeSet>& sets,
                            const Lattice& lat) {
  constexpr char kAxis[3] = {'x', 'y', 'z'};
  // The nodes two sets share (node sets are sorted): how many, and the first.
  const auto shared = [](const std::vector<index_t>& a, const std::vector<index_t>& b) {
    std::size_t count = 0;
    index_t first = 0;
    for (auto p = a.begin(), q = b.begin(); p != a.end() && q != b.end();)
      if (*p < *q) {
        ++p;
      } else if (*q < *p) {
        ++q;
      } else {
        first = count++ == 0 ? *p : first;
        ++p;
        ++q;
      }
    return std::pair{count, first};
  };
  const auto where = [&](index_t n) {
    const Vec3 x = lat.position(n);
    return fmt::format("node {} at ({:g}, {:g}, {:g}) m", n, x.x, x.y, x.z);
  };
  for (std::size_t t = 0; t < s.velocities.size(); ++t) {
    const VelocitySpec& v = s.velocities[t];
    const std::vector<index_t>& nodes = set_named(sets, v.set).nodes;
    const std::string table =
        fmt::format("velocity[{}].dofs: [[velocity]] table {} (node set \"{}\")", t, t + 1, v.set);
    for (int d = 0; d < 3; ++d) {
      const DofMask bit = static_cast<DofMask>(1u << d);
      if (!(v.dofs & bit))
        continue;
      if (s.plane_strain_axis == d)
        throw InputError(fmt::format(
            "{} imposes the {} velocity on its {} nodes, but plane_strain = \"{}\" holds {} at "
            "every node: leave {} out of the table's dofs",
            table, kAxis[d], nodes.size(), kAxis[d], kAxis[d], kAxis[d]));
      for (std::size_t f = 0; f < s.fixed.size(); ++f)
        if (s.fixed[f].dofs & bit)
          if (const auto [count, first] = shared(nodes, set_named(sets, s.fixed[f].set).nodes);
              count > 0)
            throw InputError(fmt::format(
                "{} imposes the {} velocity on {} nodes that [[fixed]] table {} (node set \"{}\") "
                "holds (the first: {}): a DOF is either held or driven; leave these nodes out of "
                "one of the two sets",
                table, kAxis[d], count, f + 1, s.fixed[f].set, where(first)));
      for (std::size_t u = 0; u < t; ++u)
        if (s.velocities[u].dofs & bit)
          if (const auto [count, first] = shared(set_named(sets, s.velocities[u].set).nodes, nodes);
              count > 0)
            throw InputError(fmt::format(
                "velocity[{}].dofs: [[velocity]] tables {} (node set \"{}\") and {} (node set "
                "\"{}\") both impose the {} velocity on {} nodes (the first: {}): one velocity per "
                "DOF; let the sets not overlap",
                t, u + 1, s.velocities[u].set, t + 1, v.set, kAxis[d], count, where(first)));
    }
  }
}

} // namespace

BarFields case_fields(const CaseSpec& s, const Lattice& whole, const std::vector<index_t>* bars,
                      const std::vector<index_t>* modules) {
  BarFields out;
  const double tol = 1e-9 * whole.L();
  // The items' numbers in the body, and where each lies.
  std::vector<index_t> all_bars, all_modules;
  if (!bars) {
    all_bars.resize(whole.num_bars());
    std::iota(all_bars.begin(), all_bars.end(), index_t{0});
    bars = &all_bars;
  }
  if (!modules) {
    all_modules.resize(whole.num_modules());
    std::iota(all_modules.begin(), all_modules.end(), index_t{0});
    modules = &all_modules;
  }
  const auto module_centre = [&](index_t m) {
    const index_t i = m % whole.nx(), j = (m / whole.nx()) % whole.ny(),
                  k = m / (whole.nx() * whole.ny());
    return whole.position(whole.centre(i, j, k));
  };
  struct Property {
    const std::optional<Field>* field;
    std::optional<double> value; // the [material]'s number where no field is given
    std::optional<Field> RegionSpec::*in_region;
    std::vector<double>* out;
    bool per_module;
  };
  const MaterialSpec& m = s.material;
  const Property props[] = {{&s.fields.E, m.E, &RegionSpec::E, &out.E, false},
                            {&s.fields.Gf, m.Gf, &RegionSpec::Gf, &out.Gf, false},
                            {&s.fields.e_p, m.e_p, &RegionSpec::e_p, &out.e_p, false},
                            {&s.fields.e_r, m.e_r, &RegionSpec::e_r, &out.e_r, false},
                            {&s.fields.R_f, m.R_f, &RegionSpec::R_f, &out.R_f, false},
                            {&s.fields.rho, m.rho, &RegionSpec::rho, &out.rho, true}};
  for (const Property& p : props) {
    const bool in_regions =
        std::any_of(s.regions.begin(), s.regions.end(),
                    [&](const RegionSpec& r) { return (r.*p.in_region).has_value(); });
    if (!*p.field && !in_regions)
      continue;
    const std::vector<index_t>& items = p.per_module ? *modules : *bars;
    auto evaluate = [&](const Field& f) {
      return p.per_module ? evaluate_field_modules(f, whole, items)
                          : evaluate_field(f, whole, items);
    };
    *p.out = *p.field ? evaluate(**p.field) : std::vector<double>(items.size(), *p.value);
    for (const RegionSpec& r : s.regions) {
      const std::optional<Field>& f = r.*p.in_region;
      if (!f)
        continue;
      std::vector<double> values = evaluate(*f);
      for (std::size_t q = 0; q < items.size(); ++q) {
        const Vec3 x = p.per_module ? module_centre(items[q]) : whole.bar_centre(items[q]);
        if (r.shape.contains(x, tol))
          (*p.out)[q] = values[q];
      }
    }
  }
  return out;
}

const NodeSet& set_named(const std::vector<NodeSet>& sets, const std::string& name) {
  for (const NodeSet& s : sets)
    if (s.name == name)
      return s;
  throw InputError("node set \"" + name + "\" is not defined");
}

std::string located(const CaseSpec& s, const std::string& path, const std::string& message) {
  // The key, else the table entry or table it is in ("load[1].traction", then "load[1]";
  // "material fields", then "material").
  const std::size_t colon = message.find(": ");
  auto at = s.key_lines.end();
  if (colon != std::string::npos)
    for (std::string key = message.substr(0, colon); !key.empty() && at == s.key_lines.end();) {
      at = s.key_lines.find(key);
      const std::size_t cut = key.find_last_of(". ");
      key = cut == std::string::npos ? std::string() : key.substr(0, cut);
    }
  return at == s.key_lines.end() ? fmt::format("{}: {}", path, message)
                                 : fmt::format("{}:{}: {}", path, at->second, message);
}

namespace {

// Runs `f`; an InputError from it is given the case entry it concerns ("precrack[0]: ..."),
// so that located() finds the entry's line.
template <class F> auto for_entry(const std::string& entry, F&& f) {
  try {
    return f();
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", entry, e.what()));
  }
}

} // namespace

void setup_progress_line(const std::string& phase, double seconds) {
  if (seconds >= 2.0 && process_rank() == 0)
    fmt::print(stderr, "ldem: set-up: {} ({:.1f} s)\n", phase, seconds);
}

BuiltCase build_case(const std::string& path, const std::function<void(CaseSpec&)>& adjust,
                     bool with_simulation, const std::string* text) {
  BuiltCase c;
  c.spec = text ? parse_case(*text, path) : read_case(path);
  if (adjust)
    adjust(c.spec);
  const CaseSpec& s = c.spec;
  try {
    Lattice lat(s.nx, s.ny, s.nz, s.L);
    if (!s.geometry.empty()) {
      const ModuleMask mask = for_entry(
          "geometry", [&] { return build_module_mask(s.nx, s.ny, s.nz, s.L, s.geometry); });
      c.hinged_modules = mask.hinged;
      c.pieces = mask.pieces;
      if (mask.hinged > 0)
        c.warnings.push_back(fmt::format(
            "geometry: {} modules removed: their pieces met the rest of the body only at edges "
            "or corners, where they would turn as about hinges",
            mask.hinged));
      if (mask.pieces > 1)
        c.warnings.push_back(fmt::format(
            "geometry: the body is in {} pieces that share no node: each moves on its own",
            mask.pieces));
      // A mask that keeps every module is the box itself, stepped as the box.
      if (mask.count < lat.num_modules())
        lat.set_modules(std::make_shared<const std::vector<std::uint8_t>>(mask.present));
    }
    for (std::size_t i = 0; i < s.node_sets.size(); ++i) {
      const NodeSetSpec& ns = s.node_sets[i];
      c.sets.push_back(for_entry(fmt::format("node_set[{}]", i),
                                 [&] { return make_node_set(ns.name, select(lat, ns), how(ns)); }));
    }
    for (std::size_t i = 0; i < s.precracks.size(); ++i) {
      const PrecrackSpec& p = s.precracks[i];
      c.cuts.push_back(for_entry(fmt::format("precrack[{}]", i),
                                 [&] { return cut_bars(lat, p.rect, p.nudge); }));
      c.precracked.insert(c.precracked.end(), c.cuts.back().bars.begin(), c.cuts.back().bars.end());
    }
    std::sort(c.precracked.begin(), c.precracked.end());
    c.precracked.erase(std::unique(c.precracked.begin(), c.precracked.end()), c.precracked.end());
    Conditions cond;
    cond.plane_strain_axis = s.plane_strain_axis;
    for (const FixedSpec& f : s.fixed)
      cond.fixed.push_back({set_named(c.sets, f.set), f.dofs});
    for (const VelocitySpec& v : s.velocities) {
      cond.velocities.push_back({set_named(c.sets, v.set), v.dofs, v.value, v.scale});
      if (v.control) {
        // The controller's response time by default: 20 times the time a bar wave takes to
        // cross the box's largest extent (docs/model.md, "Probe-controlled loading").
        const double extent =
            static_cast<double>(std::max({s.nx, s.ny, s.nz})) * s.L,
                     wave = std::sqrt(s.material.E / s.material.rho);
        BuiltCase::Control k;
        k.probe = static_cast<std::size_t>(
            std::find_if(s.probes.begin(), s.probes.end(),
                         [&](const ProbeSpec& p) { return p.name == v.control->probe; }) -
            s.probes.begin());
        k.rate = v.control->rate;
        k.response_time =
            v.control->response_time > 0.0 ? v.control->response_time : 20.0 * extent / wave;
        k.speed = std::sqrt(v.value.x * v.value.x + v.value.y * v.value.y + v.value.z * v.value.z);
        cond.velocities.back().control = static_cast<int>(c.controls.size());
        c.controls.push_back(k);
      }
    }
    for (std::size_t i = 0; i < s.loads.size(); ++i) {
      const LoadSpec& l = s.loads[i];
      const NodeSet& set = set_named(c.sets, l.set);
      std::vector<double> weight =
          for_entry(fmt::format("load[{}].{}", i,
                                l.kind == LoadSpec::Kind::Total ? "total" : "traction"),
                    [&] { return traction_weights(s, l, lat, set); });
      const Vec3 force = force_per_weight(l, weight);
      cond.loads.push_back({set, force, l.scale, std::move(weight)});
    }
    for (const PlatenSpec& p : s.platens) {
      Platen pl;
      pl.name = p.name;
      pl.kind = p.kind;
      pl.point = p.point;
      pl.normal = p.direction;
      pl.radius = p.radius;
      pl.velocity = p.velocity;
      pl.scale = p.scale;
      pl.friction = p.friction;
      pl.penalty = p.penalty;
      cond.platens.push_back(std::move(pl));
    }
    check_conditions_agree(s, c.sets, lat);
    // A gauge's end: the present node nearest a point, or a node set's nodes; and its mean
    // position.
    const auto gauge_end = [&](const std::optional<Vec3>& point, const std::string& set,
                               std::vector<index_t>& nodes) {
      if (point) {
        const index_t best = nearest(lat.num_nodes(), *point,
                                     [&](index_t n) { return lat.node_present(n); },
                                     [&](index_t n) { return lat.position(n); });
        nodes = {best};
      } else {
        nodes = set_named(c.sets, set).nodes;
      }
      Vec3 m{0.0, 0.0, 0.0};
      for (index_t n : nodes) {
        const Vec3 x = lat.position(n);
        m = {m.x + x.x, m.y + x.y, m.z + x.z};
      }
      const double k = 1.0 / static_cast<double>(nodes.size());
      return Vec3{m.x * k, m.y * k, m.z * k};
    };
    for (std::size_t i = 0; i < s.probes.size(); ++i) {
      const ProbeSpec& p = s.probes[i];
      BuiltCase::Gauge g;
      if (p.kind == ProbeSpec::Kind::Displacement) {
        gauge_end(p.has_at ? std::optional<Vec3>(p.at) : std::nullopt, p.set, g.to);
        g.component = p.component;
      } else if (p.kind == ProbeSpec::Kind::Opening || p.kind == ProbeSpec::Kind::Strain) {
        const Vec3 a = gauge_end(p.from.point, p.from.set, g.from);
        const Vec3 b = gauge_end(p.to.point, p.to.set, g.to);
        if (p.kind == ProbeSpec::Kind::Opening) {
          g.component = p.component;
        } else {
          const Vec3 d{b.x - a.x, b.y - a.y, b.z - a.z};
          const double l = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
          if (!(l > 0.0))
            throw InputError(fmt::format(
                "{}: probe[{}] (\"{}\"): expected a strain gauge with two ends apart, got both "
                "ends at [{}, {}, {}] (give from and to, or from_set and to_set, that differ)",
                c.path, i, p.name, a.x, a.y, a.z));
          g.dir = {d.x / l, d.y / l, d.z / l};
          g.scale = 1.0 / l;
        }
      }
      c.probe_gauges.push_back(std::move(g));
    }
    for (const ProbeSpec& p : s.probes) {
      index_t best = 0;
      if (p.kind == ProbeSpec::Kind::BarForce)
        best = nearest(lat.num_bars(), p.at, [&](index_t b) { return lat.bar_present(b); },
                       [&](index_t b) { return lat.bar_centre(b); });
      c.probe_bars.push_back(best);
    }
    const std::pair<const std::optional<Field>*, const char*> given[] = {
        {&s.fields.E, "material.E"},     {&s.fields.Gf, "material.Gf"},
        {&s.fields.e_p, "material.e_p"}, {&s.fields.e_r, "material.e_r"},
        {&s.fields.R_f, "material.R_f"}, {&s.fields.rho, "material.rho"}};
    for (const auto& [f, name] : given)
      if (*f)
        validate_field(**f, lat, name);
    for (std::size_t i = 0; i < s.regions.size(); ++i) {
      const RegionSpec& rg = s.regions[i];
      const std::pair<const std::optional<Field>*, const char*> in[] = {
          {&rg.E, "E"},     {&rg.Gf, "Gf"},   {&rg.e_p, "e_p"},
          {&rg.e_r, "e_r"}, {&rg.R_f, "R_f"}, {&rg.rho, "rho"}};
      for (const auto& [f, name] : in)
        if (*f)
          validate_field(**f, lat, fmt::format("region[{}].{}", i, name));
    }
    // Evaluated over the whole body only where it is built: a distributed run's other
    // processes evaluate their windows (run_body_distributed.cpp).
    BarFields fields;
    if (with_simulation)
      fields = case_fields(s, lat, nullptr, nullptr);
    if (s.material.fatigue && s.material.fatigue->jump) {
      // The cycles a jump skips: those of the case's growing_sine terms, one frequency. A
      // controlled velocity follows the body's response, which a jump does not compute.
      for (const VelocitySpec& v : s.velocities)
        if (v.control)
          throw InputError(fmt::format(
              "fatigue.jump: expected loads and velocities given by time functions (a jump "
              "skips their cycles), got a velocity on \"{}\" controlled by probe \"{}\"",
              v.set, v.control->probe));
      std::vector<const TimeFunction*> functions;
      for (const LoadSpec& l : s.loads)
        functions.push_back(&l.scale);
      for (const VelocitySpec& v : s.velocities)
        functions.push_back(&v.scale);
      for (const TimeFunction* f : functions)
        for (const TimeTerm& term : f->terms()) {
          // A jump carries the loads' cycles on unchanged: no term may end.
          const double t_end = std::visit([](const auto& x) { return x.t_end; }, term);
          if (t_end < kNever)
            throw InputError(fmt::format("fatigue.jump: expected loads whose terms go on to the "
                                         "end (a jump skips their cycles), got t_end = {:g} s",
                                         t_end));
          if (const auto* g = std::get_if<GrowingSine>(&term)) {
            if (c.cycle && c.cycle->frequency != g->frequency)
              throw InputError(fmt::format(
                  "fatigue.jump: expected the cyclic loads at one frequency, got {:g} and {:g} Hz",
                  c.cycle->frequency, g->frequency));
            const double t_constant = g->t_start + g->n_cycles / g->frequency;
            c.cycle = BuiltCase::LoadCycle{
                g->frequency, c.cycle ? std::max(c.cycle->t_constant, t_constant) : t_constant};
          }
        }
      if (!c.cycle)
        throw InputError("fatigue.jump: expected a [[load]] or [[velocity]] with a "
                         "growing_sine term (its cycles are what a jump skips), got none");
    }
    // A body force: each node of its set weighed by its lumped mass, the simulation's own
    // (lumped_masses, from the same densities).
    if (std::any_of(s.loads.begin(), s.loads.end(),
                    [](const LoadSpec& l) { return l.kind == LoadSpec::Kind::Acceleration; })) {
      const std::vector<index_t> no_bars;
      const std::vector<double> rho_module =
          with_simulation ? fields.rho : case_fields(s, lat, &no_bars, nullptr).rho;
      const auto mass = lumped_masses(lat, s.material.rho, rho_module);
      for (std::size_t i = 0; i < s.loads.size(); ++i)
        if (s.loads[i].kind == LoadSpec::Kind::Acceleration) {
          std::vector<double>& weight = cond.loads[i].weight;
          weight.clear();
          for (const index_t n : cond.loads[i].set.nodes)
            weight.push_back(mass[n]);
        }
    }
    c.lattice = lat;
    c.conditions = cond;
    c.options.step = s.step;
    c.options.step.end = s.end_time;
    c.options.damping = s.damping;
    c.options.law = find_law(s.law);
    c.options.setup_progress = setup_progress_line;
    if (!s.output.vtu_arrays.empty()) {
      const std::vector<std::string> names =
          vtu_array_names(c.options.law ? c.options.law->state_arrays
                                        : std::span<const StateArray>());
      for (const std::string& a : s.output.vtu_arrays)
        if (std::find(names.begin(), names.end(), a) == names.end()) {
          std::string list;
          for (const std::string& n : names)
            list += (list.empty() ? "\"" : ", \"") + n + "\"";
          throw InputError(fmt::format(
              "output.vtu_arrays: expected names among {} (this law's), got \"{}\"", list, a));
        }
    }
    if (s.material.fatigue && s.damping == 0.0)
      c.warnings.push_back(
          "time.damping = 0 with a fatigue law: the ringing each break sets off stays in the "
          "body, and where it passes the cycle count's gate it splits a load cycle's strain "
          "range into smaller ranges, and the bars live far longer (200 times on the LEFM plate of "
          "docs/validation/fatigue.md); give the damping that a specimen's "
          "vibrations have, or a gate above the ringing");
    if (s.material.fatigue && s.material.fatigue->box) {
      const auto& [lo, hi] = *s.material.fatigue->box;
      for (index_t b = 0; b < lat.num_bars(); ++b) {
        const auto [n0, n1] = lat.bar_nodes(b);
        if (!lat.bar_present(b) || !segment_meets_box(lat.position(n0), lat.position(n1), lo, hi))
          c.lifeless.push_back(b);
      }
      if (c.lifeless.size() == static_cast<std::size_t>(lat.num_bars()))
        throw InputError(
            fmt::format("fatigue.box_min: expected a box that at least one bar meets, got "
                        "[{:g}, {:g}, {:g}] to [{:g}, {:g}, {:g}] m",
                        lo.x, lo.y, lo.z, hi.x, hi.y, hi.z));
    }
    if (s.material.fatigue && lat.shaped()) {
      // The box's bars outside the body have no life to use up (their strains are those of
      // nodes that move against nodes that stay).
      for (index_t b = 0; b < lat.num_bars(); ++b)
        if (!lat.bar_present(b))
          c.lifeless.push_back(b);
      std::sort(c.lifeless.begin(), c.lifeless.end());
      c.lifeless.erase(std::unique(c.lifeless.begin(), c.lifeless.end()), c.lifeless.end());
    }
    if (with_simulation) {
      BarTable table(lat, s.material, fields);
      c.warnings.insert(c.warnings.end(), table.warnings().begin(), table.warnings().end());
      c.sim = std::make_unique<Simulation>(std::move(lat), std::move(table), std::move(cond),
                                           c.options, c.precracked);
      remove_fatigue_life(*c.sim, c.lifeless);
    }
  } catch (const InputError& e) {
    throw InputError(located(s, path, e.what()));
  }
  c.path = path;
  if (c.sim)
    check_end_time(c, c.sim->dt());
  return c;
}

void remove_fatigue_life(Simulation& sim, const std::vector<index_t>& bars) {
  const auto arrays = sim.bar_state_arrays();
  for (std::size_t a = 0; a < arrays.size(); ++a)
    if (arrays[a].name == "life") {
      const std::span<double> life = sim.bar_state_array(a);
      for (const index_t b : bars)
        life[b] = std::numeric_limits<double>::infinity(); // never used up (a cycle's share
                                                           // leaves it infinite)
    }
}

void check_end_time(const BuiltCase& c, double dt) {
  if (!(c.spec.end_time >= dt))
    throw InputError(located(c.spec, c.path,
                             fmt::format("time.end: expected at least one time step ({:.4g} s), "
                                         "got {:g} s",
                                         dt, c.spec.end_time)));
}

BodyNumbers body_numbers(const Simulation& sim) {
  return {sim.table().ranges(),   sim.table().ductility_summary(),
          sim.stable_step(),      sim.dt(),
          sim.bytes_per_module(), sim.table().per_bar()};
}

std::string resolved_case_toml(const BuiltCase& c, const BodyNumbers& body) {
  const CaseSpec& s = c.spec;
  const Lattice& lat = *c.lattice;
  auto vec = [](Vec3 v) { return toml::array{v.x, v.y, v.z}; };
  toml::table root;
  root.insert("case", toml::table{{"title", s.title}});
  root.insert("lattice",
              toml::table{{"modules", toml::array{s.nx, s.ny, s.nz}},
                          {"L", s.L},
                          {"plane_strain",
                           s.plane_strain_axis < 0
                               ? std::string("none")
                               : std::string(1, static_cast<char>('x' + s.plane_strain_axis))}});
  if (!s.geometry.empty()) {
    toml::array ops;
    for (const ShapeOp& op : s.geometry)
      ops.push_back(toml::table{{op.add ? "add" : "remove", shape_table(op.shape)}});
    root.insert("geometry", ops);
    root["lattice"].as_table()->insert("hinged_modules_removed",
                                       static_cast<std::int64_t>(c.hinged_modules));
    root["lattice"].as_table()->insert("pieces", static_cast<std::int64_t>(c.pieces));
    root["lattice"].as_table()->insert("modules_present",
                                       static_cast<std::int64_t>(lat.num_present_modules()));
    root["lattice"].as_table()->insert("volume", lat.volume());
  }
  if (!s.regions.empty()) {
    toml::array regions;
    for (const RegionSpec& r : s.regions) {
      toml::table t{{"shape", shape_table(r.shape)}};
      const std::pair<const char*, const std::optional<Field>*> props[] = {
          {"E", &r.E},     {"Gf", &r.Gf},   {"e_p", &r.e_p},
          {"e_r", &r.e_r}, {"R_f", &r.R_f}, {"rho", &r.rho}};
      for (const auto& [name, f] : props)
        if (*f) {
          if ((*f)->kind == Field::Kind::Constant)
            t.insert(name, (*f)->value);
          else
            t.insert(name, describe_field(**f));
        }
      regions.push_back(std::move(t));
    }
    root.insert("region", regions);
  }
  toml::table mat{{"law", s.law},
                  {"E", s.material.E},
                  {"nu", s.material.nu},
                  {"rho", s.material.rho},
                  {"Gf", s.material.Gf},
                  {"single_ratio", s.material.single_ratio},
                  {"allow_low_kr", s.material.allow_low_kr}};
  if (s.material.e_p)
    mat.insert("e_p", *s.material.e_p);
  if (s.material.R_f)
    mat.insert("R_f", *s.material.R_f);
  if (s.material.e_r)
    mat.insert("e_r", *s.material.e_r);
  if (const auto& f = s.material.fatigue)
    root.insert("fatigue", toml::table{{"A", f->A},
                                       {"m", f->m},
                                       {"threshold", f->threshold},
                                       {"length", f->length},
                                       {"count_every", static_cast<std::int64_t>(f->count_every)},
                                       {"jump", f->jump}});
  if (const auto& f = s.material.fatigue; f && f->jump) {
    toml::table& t = *root["fatigue"].as_table();
    t.insert("jump_window", static_cast<std::int64_t>(f->jump_window));
    t.insert("jump_breaks", static_cast<std::int64_t>(f->jump_breaks));
    t.insert("jump_max", f->jump_max);
    t.insert("jump_fraction", f->jump_fraction);
  }
  if (const auto& f = s.material.fatigue; f && f->box) {
    toml::table& t = *root["fatigue"].as_table();
    const auto& [lo, hi] = *f->box;
    t.insert("box_min", toml::array{lo.x, lo.y, lo.z});
    t.insert("box_max", toml::array{hi.x, hi.y, hi.z});
    t.insert("bars_with_life", static_cast<std::int64_t>(c.lattice->num_bars()) -
                                   static_cast<std::int64_t>(c.lifeless.size()));
  }
  if (const auto& f = s.material.fatigue) {
    // The gate as given, or the default as a strain range: 1 % of e_p, its range over the bars.
    toml::table& t = *root["fatigue"].as_table();
    if (f->gate > 0.0)
      t.insert("gate", f->gate);
    else if (body.ranges.e_p[0] == body.ranges.e_p[1])
      t.insert("gate", kDefaultGate * body.ranges.e_p[0]);
    else
      t.insert("gate",
               toml::array{kDefaultGate * body.ranges.e_p[0], kDefaultGate * body.ranges.e_p[1]});
  }
  const std::pair<const char*, const std::optional<Field>*> field_of[] = {
      {"E", &s.fields.E},     {"Gf", &s.fields.Gf},   {"e_p", &s.fields.e_p},
      {"e_r", &s.fields.e_r}, {"R_f", &s.fields.R_f}, {"rho", &s.fields.rho}};
  toml::table fields_table;
  for (const auto& [name, f] : field_of)
    if (*f) {
      mat.insert_or_assign(name, describe_field(**f)); // the field, described in words
      if ((*f)->kind == Field::Kind::Weibull) {
        const double g = weibull_shape((*f)->cv);
        fields_table.insert(name, toml::table{{"kind", "weibull"},
                                              {"mean", (*f)->mean},
                                              {"cv", (*f)->cv},
                                              {"shape", g},
                                              {"scale", weibull_scale((*f)->mean, g)},
                                              {"correlation_length", (*f)->correlation_length}});
      } else {
        fields_table.insert(
            name, toml::table{{"kind", (*f)->kind == Field::Kind::Linear ? "linear" : "table"}});
      }
    }
  if (!fields_table.empty())
    root.insert("fields", fields_table);
  const MaterialRanges& mr = body.ranges;
  mat.insert("rule", mr.rule);
  mat.insert("E_range", toml::array{mr.E[0], mr.E[1]});
  mat.insert("Gf_range", toml::array{mr.Gf[0], mr.Gf[1]});
  mat.insert("e_p_range", toml::array{mr.e_p[0], mr.e_p[1]});
  mat.insert("e_r_normal_range", toml::array{mr.e_r_normal[0], mr.e_r_normal[1]});
  mat.insert("rho_range", toml::array{mr.rho[0], mr.rho[1]});
  root.insert("material", mat);
  toml::array sets;
  for (std::size_t i = 0; i < s.node_sets.size(); ++i) {
    const NodeSetSpec& n = s.node_sets[i];
    toml::table t{{"name", n.name}};
    if (n.kind == NodeSetSpec::Kind::Face)
      t.insert("face", face_name(n.face));
    else if (n.kind == NodeSetSpec::Kind::FaceCentres)
      t.insert("face_centres", face_name(n.face));
    else if (n.kind == NodeSetSpec::Kind::Box) {
      t.insert("box_min", vec(n.lo));
      t.insert("box_max", vec(n.hi));
    } else if (n.kind == NodeSetSpec::Kind::Shape)
      t.insert("shape", shape_table(n.shape));
    else
      t.insert("all", true);
    t.insert("nodes_selected", static_cast<std::int64_t>(c.sets[i].nodes.size()));
    sets.push_back(t);
  }
  if (!sets.empty())
    root.insert("node_set", sets);
  auto function = [](const TimeFunction& f) {
    toml::array terms;
    for (const TimeTerm& term : f.terms())
      std::visit(
          [&terms](const auto& t) {
            using T = std::decay_t<decltype(t)>;
            if constexpr (std::is_same_v<T, Constant>) {
              terms.push_back(toml::table{{"type", "constant"}, {"value", t.value}});
            } else if constexpr (std::is_same_v<T, LinearRamp>) {
              terms.push_back(
                  toml::table{{"type", "ramp"}, {"value", t.value}, {"duration", t.duration}});
            } else if constexpr (std::is_same_v<T, ExponentialRise>) {
              terms.push_back(
                  toml::table{{"type", "exp_rise"}, {"value", t.value}, {"tau", t.tau}});
            } else if constexpr (std::is_same_v<T, GrowingSine>) {
              terms.push_back(toml::table{{"type", "growing_sine"},
                                          {"amplitude", t.amplitude},
                                          {"frequency", t.frequency},
                                          {"tau", t.tau},
                                          {"n_cycles", t.n_cycles}});
            } else {
              toml::array points;
              for (std::size_t k = 0; k < t.times.size(); ++k)
                points.push_back(toml::array{t.times[k], t.values[k]});
              terms.push_back(toml::table{{"type", "table"}, {"points", points}});
            }
            // Its window, where it is not the whole run's.
            toml::table& w = *terms.back().as_table();
            if (t.t_start > 0.0 || std::is_same_v<T, GrowingSine>)
              w.insert("t_start", t.t_start);
            if (t.t_end < kNever)
              w.insert("t_end", t.t_end);
          },
          term);
    // Inline tables ({ type = ... }), as a case writes them.
    for (auto& t : terms)
      t.as_table()->is_inline(true);
    return terms;
  };
  toml::array fixed, vel, loads, platens, cracks, probes;
  for (const FixedSpec& f : s.fixed)
    fixed.push_back(toml::table{{"set", f.set}, {"dofs", dofs_text(f.dofs)}});
  std::size_t next_control = 0;
  for (const VelocitySpec& v : s.velocities) {
    toml::table t{{"set", v.set}, {"dofs", dofs_text(v.dofs)}, {"value", vec(v.value)}};
    if (v.control) {
      // The controller as it runs: its response time resolved.
      toml::table control{{"probe", v.control->probe},
                          {"rate", v.control->rate},
                          {"response_time", c.controls[next_control++].response_time}};
      control.is_inline(true);
      t.insert("control", std::move(control));
    } else {
      t.insert("function", function(v.scale));
    }
    vel.push_back(std::move(t));
  }
  for (std::size_t i = 0; i < s.loads.size(); ++i) {
    const LoadSpec& l = s.loads[i];
    static const char* const kinds[] = {"force", "traction", "total", "acceleration"};
    toml::table t{{"name", l.name},
                  {"set", l.set},
                  {kinds[static_cast<int>(l.kind)], vec(l.force)},
                  {"function", function(l.scale)}};
    // The area a traction or total acts on, or the mass a body force acts on: its nodes'
    // weights added.
    double weight = 0.0;
    for (double a : c.conditions.loads[i].weight)
      weight += a;
    if (l.kind == LoadSpec::Kind::Traction || l.kind == LoadSpec::Kind::Total)
      t.insert("area", weight);
    if (l.kind == LoadSpec::Kind::Acceleration)
      t.insert("mass", weight);
    loads.push_back(std::move(t));
  }
  for (const PlatenSpec& p : s.platens) {
    const bool plane = p.kind == Platen::Kind::Plane;
    toml::table t{{"name", p.name}, {"shape", plane ? "plane" : "cylinder"}, {"point", vec(p.point)}};
    t.insert(plane ? "normal" : "axis", vec(p.direction));
    if (!plane)
      t.insert("radius", p.radius);
    t.insert("velocity", vec(p.velocity));
    t.insert("function", function(p.scale));
    t.insert("friction", p.friction);
    t.insert("penalty", p.penalty);
    platens.push_back(std::move(t));
  }
  for (std::size_t i = 0; i < s.precracks.size(); ++i) {
    const PrecrackSpec& p = s.precracks[i];
    cracks.push_back(toml::table{{"name", p.rect.name},
                                 {"origin", vec(c.cuts[i].origin)},
                                 {"edge1", vec(p.rect.edge1)},
                                 {"edge2", vec(p.rect.edge2)},
                                 {"nudge", p.nudge},
                                 {"nudged", c.cuts[i].nudged},
                                 {"bars_cut", static_cast<std::int64_t>(c.cuts[i].bars.size())}});
  }
  for (std::size_t i = 0; i < s.probes.size(); ++i) {
    const ProbeSpec& p = s.probes[i];
    toml::table t{{"name", p.name}};
    if (p.kind == ProbeSpec::Kind::BarForce) {
      t.insert("kind", "bar_force");
      t.insert("at", vec(p.at));
      t.insert("bar", static_cast<std::int64_t>(c.probe_bars[i]));
    } else if (p.kind == ProbeSpec::Kind::Reaction) {
      t.insert("kind", "reaction");
      t.insert("set", p.set);
      t.insert("component", std::string(1, static_cast<char>('x' + p.component)));
    } else if (p.kind == ProbeSpec::Kind::Displacement || p.kind == ProbeSpec::Kind::Opening ||
               p.kind == ProbeSpec::Kind::Strain) {
      // The gauge as found: each end's point or set, and the node a point took.
      const BuiltCase::Gauge& g = c.probe_gauges[i];
      const auto node_of = [&](const std::vector<index_t>& nodes) {
        return toml::table{{"node", static_cast<std::int64_t>(nodes[0])},
                           {"position", vec(c.lattice->position(nodes[0]))}};
      };
      if (p.kind == ProbeSpec::Kind::Displacement) {
        t.insert("kind", "displacement");
        if (p.has_at) {
          t.insert("at", vec(p.at));
          t.insert("node", node_of(g.to));
        } else {
          t.insert("set", p.set);
        }
      } else {
        t.insert("kind", p.kind == ProbeSpec::Kind::Opening ? "opening" : "strain");
        const auto end = [&](const ProbeSpec::End& e, const char* point, const char* set,
                             const std::vector<index_t>& nodes) {
          if (e.point) {
            t.insert(point, vec(*e.point));
            t.insert(std::string(point) + "_node", node_of(nodes));
          } else {
            t.insert(set, e.set);
          }
        };
        end(p.from, "from", "from_set", g.from);
        end(p.to, "to", "to_set", g.to);
        if (p.kind == ProbeSpec::Kind::Strain)
          t.insert("gauge_length", 1.0 / g.scale);
      }
      if (p.kind != ProbeSpec::Kind::Strain)
        t.insert("component", std::string(1, static_cast<char>('x' + p.component)));
    } else if (p.kind == ProbeSpec::Kind::Platen ||
               p.kind == ProbeSpec::Kind::PlatenDisplacement) {
      t.insert("kind", p.kind == ProbeSpec::Kind::Platen ? "platen" : "platen_displacement");
      t.insert("platen", p.platen);
      t.insert("component", std::string(1, static_cast<char>('x' + p.component)));
    } else {
      t.insert("kind", "load");
      t.insert("load", p.load);
    }
    probes.push_back(t);
  }
  if (!fixed.empty())
    root.insert("fixed", fixed);
  if (!vel.empty())
    root.insert("velocity", vel);
  if (!loads.empty())
    root.insert("load", loads);
  if (!platens.empty())
    root.insert("platen", platens);
  if (!cracks.empty())
    root.insert("precrack", cracks);
  const char* rule = s.step.rule == TimeStep::Rule::Given   ? "dt"
                     : s.step.rule == TimeStep::Rule::Paper ? "paper"
                                                            : "safety";
  root.insert("time", toml::table{{"end", s.end_time},
                                  {"rule", rule},
                                  {"safety", s.step.safety},
                                  {"courant", s.step.courant},
                                  {"dt", body.dt},
                                  {"damping", s.damping}});
  if (s.stop_displacement > 0)
    root["time"].as_table()->insert("stop_displacement", s.stop_displacement);
  root.insert("output",
              toml::table{{"energy_every", static_cast<std::int64_t>(s.output.energy_every)},
                          {"vtu_every", static_cast<std::int64_t>(s.output.vtu_every)},
                          {"vtu", s.output.vtu},
                          {"plots", s.output.plots}});
  if (s.output.vtu_zlib)
    root["output"].as_table()->insert("vtu_compression", "zlib");
  if (!s.output.vtu_arrays.empty()) {
    toml::array arrays;
    for (const std::string& a : s.output.vtu_arrays)
      arrays.push_back(a);
    root["output"].as_table()->insert("vtu_arrays", arrays);
  }
  if (!probes.empty())
    root.insert("probe", probes);
  {
    toml::table an{{"crack", s.analysis.crack}};
    if (s.analysis.min_branch_length > 0)
      an.insert("min_branch_length", s.analysis.min_branch_length);
    if (s.analysis.branch_fit_length > 0)
      an.insert("branch_fit_length", s.analysis.branch_fit_length);
    if (s.analysis.speed_window > 0)
      an.insert("speed_window", s.analysis.speed_window);
    if (s.analysis.speed_fit_length > 0)
      an.insert("speed_fit_length", s.analysis.speed_fit_length);
    if (s.analysis.zone_flag_length > 0)
      an.insert("zone_flag_length", s.analysis.zone_flag_length);
    an.insert("fatigue", s.analysis.fatigue);
    if (!s.analysis.fatigue_load.empty())
      an.insert("fatigue_load", s.analysis.fatigue_load);
    an.insert("fatigue_points", s.analysis.fatigue_points);
    an.insert("fatigue_window", s.analysis.fatigue_window);
    an.insert("fatigue_rate", s.analysis.fatigue_rate);
    an.insert("fatigue_fit_after", s.analysis.fatigue_fit_after);
    an.insert("fatigue_fit_elastic", s.analysis.fatigue_fit_elastic);
    if (s.analysis.fatigue_band > 0)
      an.insert("fatigue_band", s.analysis.fatigue_band);
    if (s.analysis.fatigue_unstable_advance > 0)
      an.insert("fatigue_unstable_advance", s.analysis.fatigue_unstable_advance);
    if (s.analysis.fatigue_width > 0)
      an.insert("fatigue_width", s.analysis.fatigue_width);
    root.insert("analysis", an);
  }
  const DuctilitySummary& k = body.ductility;
  // The fastest bar wave speed, as the paper's step rule takes it.
  const double c_bar = std::sqrt(body.ranges.E[1] / body.ranges.rho[0]);
  root.insert("resolved",
              toml::table{{"nodes", static_cast<std::int64_t>(lat.num_present_nodes())},
                          {"bars", static_cast<std::int64_t>(lat.num_present_bars())},
                          {"steps", static_cast<std::int64_t>(std::ceil(s.end_time / body.dt))},
                          {"dt", body.dt},
                          {"dt_over_L_c", body.dt * c_bar / s.L},
                          {"dt_stable", body.stable.dt},
                          {"dt_stable_over_L_c", body.stable.dt * c_bar / s.L},
                          {"dt_proven_bound", body.stable.dt_bound},
                          {"dt_over_proven_bound", body.dt / body.stable.dt_bound},
                          {"K_r_normal_min", k.kr_min_normal},
                          {"K_r_normal_max", k.kr_max_normal},
                          {"K_r_diagonal_min", k.kr_min_diag},
                          {"K_r_diagonal_max", k.kr_max_diag},
                          {"L_cr", k.L_cr_min},
                          {"precracked_bars", static_cast<std::int64_t>(c.precracked.size())}});
  toml::array warnings;
  for (const std::string& w : c.warnings)
    warnings.push_back(w);
  if (const auto w = time_step_warning(body))
    warnings.push_back(*w);
  if (!warnings.empty())
    root["resolved"].as_table()->insert("warnings", warnings);
  std::ostringstream os;
  os << "# The case as run: every default and derived value ([resolved]).\n" << root << "\n";
  return os.str();
}

std::optional<std::string> time_step_warning(const BodyNumbers& b) {
  if (!(b.dt > b.stable.dt_bound))
    return std::nullopt;
  return fmt::format(
      "time step: dt = {:.4g} s is {:.0f} % above {:.4g} s, the step proven stable (Gershgorin's "
      "bound on the largest eigenfrequency); it is stable by the Lanczos estimate of the stable "
      "step, {:.4g} s, which the run relies on. For a step stable for certain, take dt <= {:.4g} s "
      "(rule = \"safety\" with safety <= {:.3f})",
      b.dt, 100.0 * (b.dt / b.stable.dt_bound - 1.0), b.stable.dt_bound, b.stable.dt,
      b.stable.dt_bound, b.stable.dt_bound / b.stable.dt);
}

} // namespace ldem
