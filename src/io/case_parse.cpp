// Reading a case file into a CaseSpec, with located, specific errors.
#include "io/case_spec.hpp"
#include "util/error.hpp"
#include "util/text_file.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>
#include <toml++/toml.h>

namespace ldem {

namespace {

std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j)
    row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t prev = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t cur = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, prev + (a[i - 1] == b[j - 1] ? 0 : 1)});
      prev = cur;
    }
  }
  return row[b.size()];
}

std::vector<std::string> split_choices(const std::string& choices) {
  std::vector<std::string> out;
  std::string cur;
  bool in = false;
  for (char c : choices) {
    if (c == '"') {
      if (in)
        out.push_back(cur);
      cur.clear();
      in = !in;
    } else if (in) {
      cur += c;
    }
  }
  return out;
}

const char* kTopTables[] = {"case", "lattice", "material", "fatigue", "time", "output", "analysis"};
const char* kArrayTables[] = {"geometry", "region", "node_set", "fixed",  "velocity",
                              "load",     "platen", "precrack", "probe"};

class Reader {
public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const toml::node* at, const std::string& key,
                         const std::string& msg) const {
    const int line = at ? static_cast<int>(at->source().begin.line) : 0;
    throw InputError(line > 0 ? fmt::format("{}:{}: {}: {}", file_, line, key, msg)
                              : fmt::format("{}: {}: {}", file_, key, msg));
  }

  // Refuses, like an unknown key, a key of `t` that is declared but does not apply to what the
  // table is (`what`, e.g. a "ramp" term): only `keys` do.
  void only(const toml::table& t, const std::string& where, const std::string& what,
            std::initializer_list<std::string_view> keys) const {
    for (const auto& [key, node] : t)
      if (std::find(keys.begin(), keys.end(), key.str()) == keys.end()) {
        std::string list;
        for (std::string_view k : keys)
          list += (list.empty() ? "" : ", ") + std::string(k);
        fail(&node, where + std::string(key.str()),
             fmt::format("does not apply to {} (its keys: {})", what, list));
      }
  }

  const KeyDecl& decl(const char* table, const char* key) const {
    for (const KeyDecl& k : case_keys())
      if (std::string(k.table) == table && std::string(k.key) == key)
        return k;
    throw std::logic_error(fmt::format("undeclared case key {}.{}", table, key));
  }

  // Every key of `t` must be declared for `table`; a close match is suggested.
  void check_known(const toml::table& t, const char* table, const std::string& where) const {
    for (const auto& [k, node] : t) {
      const std::string key(k.str());
      bool known = false;
      std::string best;
      std::size_t best_d = 3;
      for (const KeyDecl& d : case_keys()) {
        if (std::string(d.table) != table)
          continue;
        if (key == d.key || (std::string(table) == "velocity" && key == "function") ||
            (std::string(table) == "load" && key == "function") ||
            (std::string(table) == "platen" && key == "function")) {
          known = true;
          break;
        }
        const std::size_t dist = edit_distance(key, d.key);
        if (dist < best_d) {
          best_d = dist;
          best = d.key;
        }
      }
      if (!known)
        fail(&node, where + key,
             best.empty() ? fmt::format("unknown key in [{}]", table)
                          : fmt::format("unknown key in [{}]; did you mean \"{}\"?", table, best));
    }
  }

  const toml::node* find(const toml::table& t, const char* key) const { return t.get(key); }

  bool has(const toml::table& t, const char* key) const { return t.contains(key); }

  std::string describe(const toml::node& n) const {
    std::ostringstream os;
    if (n.is_string())
      os << '"' << *n.value<std::string>() << '"';
    else if (n.is_table())
      os << "a table";
    else if (n.is_array())
      os << "an array of " << n.as_array()->size();
    else
      n.visit([&os](const auto& v) {
        if constexpr (toml::is_value<decltype(v)>)
          os << v;
      });
    return os.str();
  }

  void check_range(const KeyDecl& d, const toml::node* at, const std::string& key, double v) const {
    const bool ok = (d.lo_open ? v > d.lo : v >= d.lo) && (d.hi_open ? v < d.hi : v <= d.hi) &&
                    std::isfinite(v);
    if (!ok)
      fail(at, key,
           fmt::format("expected a value {}{}, got {:g}", d.range_text(),
                       *d.unit ? fmt::format(" ({})", d.unit) : "", v));
  }

  // The key's node, or nullptr when the key is absent; a missing required key is an error.
  const toml::node* lookup(const toml::table& t, const KeyDecl& d, const std::string& name) const {
    const toml::node* n = t.get(d.key);
    if (!n && std::string(d.fallback) == "required")
      fail(&t, name, "missing required key");
    if (n && lines_)
      (*lines_)[name] = static_cast<int>(n->source().begin.line);
    return n;
  }
  // Where each key read is (CaseSpec::key_lines), for errors found after reading.
  std::map<std::string, int>* lines_ = nullptr;
  static bool no_default(const KeyDecl& d) { return std::string(d.fallback) == "-"; }

  std::optional<double> opt_float(const toml::table& t, const char* table, const char* key,
                                  const std::string& where) const {
    const KeyDecl& d = decl(table, key);
    const std::string name = where + key;
    const toml::node* n = lookup(t, d, name);
    if (!n)
      return no_default(d) ? std::nullopt : std::optional<double>(std::stod(d.fallback));
    if (!n->is_number())
      fail(n, name,
           fmt::format("expected a number{}, got {}", *d.unit ? fmt::format(" ({})", d.unit) : "",
                       describe(*n)));
    const double v =
        n->is_integer() ? static_cast<double>(*n->value<std::int64_t>()) : *n->value<double>();
    check_range(d, n, name, v);
    return v;
  }
  double get_float(const toml::table& t, const char* table, const char* key,
                   const std::string& where) const {
    return *opt_float(t, table, key, where);
  }

  std::int64_t get_int(const toml::table& t, const char* table, const char* key,
                       const std::string& where) const {
    const KeyDecl& d = decl(table, key);
    const std::string name = where + key;
    const toml::node* n = lookup(t, d, name);
    if (!n)
      return std::stoll(d.fallback);
    if (!n->is_integer())
      fail(n, name, fmt::format("expected an integer, got {}", describe(*n)));
    const auto v = *n->value<std::int64_t>();
    check_range(d, n, name, static_cast<double>(v));
    return v;
  }

  bool get_bool(const toml::table& t, const char* table, const char* key,
                const std::string& where) const {
    const KeyDecl& d = decl(table, key);
    const toml::node* n = lookup(t, d, where + key);
    if (!n)
      return std::string(d.fallback) == "true";
    if (!n->is_boolean())
      fail(n, where + key, fmt::format("expected true or false, got {}", describe(*n)));
    return *n->value<bool>();
  }

  std::optional<std::string> opt_string(const toml::table& t, const char* table, const char* key,
                                        const std::string& where) const {
    const KeyDecl& d = decl(table, key);
    const std::string name = where + key;
    const toml::node* n = lookup(t, d, name);
    if (!n) {
      if (no_default(d))
        return std::nullopt;
      const auto quoted = split_choices(d.fallback);
      return quoted.empty() ? std::string() : quoted[0];
    }
    if (!n->is_string())
      fail(n, name, fmt::format("expected a string, got {}", describe(*n)));
    const std::string v = *n->value<std::string>();
    const auto choices = split_choices(d.choices);
    if (!choices.empty() && std::find(choices.begin(), choices.end(), v) == choices.end())
      fail(n, name, fmt::format("expected {}, got \"{}\"", d.range_text(), v));
    return v;
  }
  std::string get_string(const toml::table& t, const char* table, const char* key,
                         const std::string& where) const {
    return *opt_string(t, table, key, where);
  }

  std::optional<Vec3> opt_vec3(const toml::table& t, const char* table, const char* key,
                               const std::string& where) const {
    const KeyDecl& d = decl(table, key);
    const std::string name = where + key;
    const toml::node* n = lookup(t, d, name);
    if (!n)
      return std::nullopt;
    const toml::array* a = n->as_array();
    if (!a || a->size() != 3 ||
        !std::all_of(a->begin(), a->end(), [](const toml::node& e) { return e.is_number(); }))
      fail(n, name,
           fmt::format("expected 3 numbers [x, y, z]{}, got {}",
                       *d.unit ? fmt::format(" ({})", d.unit) : "", describe(*n)));
    double v[3];
    for (int i = 0; i < 3; ++i) {
      const toml::node& e = (*a)[static_cast<std::size_t>(i)];
      v[i] = e.is_integer() ? static_cast<double>(*e.value<std::int64_t>()) : *e.value<double>();
      if (!std::isfinite(v[i]))
        fail(n, name,
             fmt::format("expected 3 finite numbers [x, y, z]{}, got {}",
                         *d.unit ? fmt::format(" ({})", d.unit) : "", describe(*n)));
    }
    return Vec3{v[0], v[1], v[2]};
  }

  DofMask dofs(const toml::table& t, const char* table, const std::string& where) const {
    const std::string s = get_string(t, table, "dofs", where);
    DofMask m = 0;
    for (char c : s) {
      if (c < 'x' || c > 'z')
        fail(find(t, "dofs"), where + "dofs",
             fmt::format("expected letters among x, y, z, got \"{}\"", s));
      m |= static_cast<DofMask>(1u << (c - 'x'));
    }
    if (m == 0)
      fail(find(t, "dofs"), where + "dofs", "expected at least one of x, y, z, got \"\"");
    return m;
  }

  TimeFunction function(const toml::table& t, const std::string& where) const {
    const toml::node* n = find(t, "function");
    if (!n)
      return TimeFunction();
    const toml::array* a = n->as_array();
    if (!a || a->empty())
      fail(n, where + "function",
           fmt::format("expected an array of tables {{ type = ... }}, got {}", describe(*n)));
    std::vector<TimeTerm> terms;
    for (std::size_t i = 0; i < a->size(); ++i) {
      const toml::table* term = (*a)[i].as_table();
      const std::string w = fmt::format("{}function[{}].", where, i);
      if (!term)
        fail(&(*a)[i], w,
             fmt::format("expected a table {{ type = ... }}, got {}", describe((*a)[i])));
      check_known(*term, "function", w);
      const std::string type = get_string(*term, "function", "type", w);
      const std::string what = fmt::format("a \"{}\" term", type);
      if (type == "constant")
        only(*term, w, what, {"type", "value", "t_start", "t_end"});
      else if (type == "ramp")
        only(*term, w, what, {"type", "value", "duration", "t_start", "t_end"});
      else if (type == "exp_rise")
        only(*term, w, what, {"type", "value", "tau", "t_start", "t_end"});
      else if (type == "table")
        only(*term, w, what, {"type", "points", "t_start", "t_end"});
      else
        only(*term, w, what,
             {"type", "amplitude", "frequency", "t_start", "tau", "n_cycles", "t_end"});
      auto need = [&](const char* key) {
        const auto v = opt_float(*term, "function", key, w);
        if (!v)
          fail(term, w + key, fmt::format("required for a \"{}\" term", type));
        return *v;
      };
      const double value = get_float(*term, "function", "value", w);
      const double t_start = get_float(*term, "function", "t_start", w);
      const double t_end = opt_float(*term, "function", "t_end", w).value_or(kNever);
      // A table's points: [[s, value], ...].
      const auto table = [&] {
        const toml::node* pn = find(*term, "points");
        if (!pn)
          fail(term, w + "points", "required for a \"table\" term");
        const toml::array* pa = pn->as_array();
        if (!pa || pa->empty())
          fail(pn, w + "points",
               fmt::format("expected points [[s, value], ...], got {}", describe(*pn)));
        Tabulated f;
        for (std::size_t k = 0; k < pa->size(); ++k) {
          const toml::array* pt = (*pa)[k].as_array();
          if (!pt || pt->size() != 2 || !(*pt)[0].is_number() || !(*pt)[1].is_number())
            fail(&(*pa)[k], fmt::format("{}points[{}]", w, k),
                 fmt::format("expected a point [s, value] of two numbers, got {}",
                             describe((*pa)[k])));
          const auto num = [](const toml::node& e) {
            return e.is_integer() ? static_cast<double>(*e.value<std::int64_t>())
                                  : *e.value<double>();
          };
          f.times.push_back(num((*pt)[0]));
          f.values.push_back(num((*pt)[1]));
          if (k > 0 && !(f.times[k] > f.times[k - 1]))
            fail(&(*pa)[k], fmt::format("{}points[{}]", w, k),
                 fmt::format("expected times that increase, got s = {:g} after s = {:g}",
                             f.times[k], f.times[k - 1]));
        }
        f.t_start = t_start;
        f.t_end = t_end;
        return f;
      };
      try {
        if (type == "constant")
          terms.emplace_back(Constant{value, t_start, t_end});
        else if (type == "ramp")
          terms.emplace_back(LinearRamp{value, need("duration"), t_start, t_end});
        else if (type == "exp_rise")
          terms.emplace_back(ExponentialRise{value, need("tau"), t_start, t_end});
        else if (type == "table")
          terms.emplace_back(table());
        else
          terms.emplace_back(GrowingSine{need("amplitude"), need("frequency"), t_start,
                                         need("tau"),
                                         get_float(*term, "function", "n_cycles", w), t_end});
        if (!(t_end > t_start))
          fail(find(*term, "t_end"), w + "t_end",
               fmt::format("expected a time after t_start = {:g}, got {:g}", t_start, t_end));
      } catch (const InputError& e) {
        fail(term, w, e.what());
      }
    }
    return TimeFunction(std::move(terms));
  }

  // A property that is a number or a field table; `extent` is the body's size per axis.
  std::optional<Field> opt_field(const toml::table& mat, const char* key, const double extent[3],
                                 const std::string& where = "material.") const {
    const toml::node* n = mat.get(key);
    const std::string name = where + key;
    if (!n || !n->is_table())
      return std::nullopt;
    const toml::table& t = *n->as_table();
    const std::string w = name + ".";
    check_known(t, "field", w);
    Field f;
    const std::string type = get_string(t, "field", "type", w);
    const std::string field_kind = fmt::format("a \"{}\" field", type);
    if (type == "linear")
      only(t, w, field_kind, {"type", "axis", "values", "at"});
    else if (type == "table")
      only(t, w, field_kind, {"type", "axis", "points"});
    else if (get_float(t, "field", "correlation_length", w) > 0.0)
      only(t, w, field_kind, {"type", "mean", "cv", "seed", "correlation_length", "covariance"});
    else
      only(t, w, "an uncorrelated \"weibull\" field (correlation_length = 0)",
           {"type", "mean", "cv", "seed", "correlation_length"});
    const std::string axis = get_string(t, "field", "axis", w);
    f.axis = axis[0] - 'x';
    auto pairs = [&](const char* k, const char* what) {
      const toml::node* a = t.get(k);
      const toml::array* arr = a ? a->as_array() : nullptr;
      if (!arr)
        fail(a ? a : &t, w + k, fmt::format("expected {}", what));
      return arr;
    };
    auto number = [&](const toml::node& e, const std::string& at_key) {
      if (!e.is_number())
        fail(&e, at_key, fmt::format("expected a number, got {}", describe(e)));
      const double v =
          e.is_integer() ? static_cast<double>(*e.value<std::int64_t>()) : *e.value<double>();
      if (!std::isfinite(v))
        fail(&e, at_key, fmt::format("expected a finite number, got {}", describe(e)));
      return v;
    };
    if (type == "linear") {
      f.kind = Field::Kind::Linear;
      const toml::array* v = pairs("values", "values = [start, end]");
      if (v->size() != 2)
        fail(t.get("values"), w + "values", fmt::format("expected 2 numbers, got {}", v->size()));
      double at[2] = {0.0, extent[f.axis]};
      if (const toml::node* a = t.get("at")) {
        const toml::array* arr = a->as_array();
        if (!arr || arr->size() != 2)
          fail(a, w + "at",
               fmt::format("expected 2 coordinates [start, end] (m), got {}", describe(*a)));
        at[0] = number((*arr)[0], w + "at");
        at[1] = number((*arr)[1], w + "at");
      }
      f.table = {{at[0], number((*v)[0], w + "values")}, {at[1], number((*v)[1], w + "values")}};
    } else if (type == "table") {
      f.kind = Field::Kind::Table;
      const toml::array* pts = pairs("points", "points = [[coordinate, value], ...]");
      for (const toml::node& p : *pts) {
        const toml::array* pr = p.as_array();
        if (!pr || pr->size() != 2)
          fail(&p, w + "points", fmt::format("expected [coordinate, value], got {}", describe(p)));
        f.table.emplace_back(number((*pr)[0], w + "points"), number((*pr)[1], w + "points"));
      }
    } else {
      f.kind = Field::Kind::Weibull;
      const std::optional<double> mean = opt_float(t, "field", "mean", w);
      const toml::node* cv = t.get("cv");
      if (!mean)
        fail(&t, w + "mean", "missing: a weibull field needs mean and cv");
      if (!cv || !cv->is_number())
        fail(cv ? cv : &t, w + "cv", "expected the coefficient of variation, a number");
      f.mean = *mean;
      f.cv = number(*cv, w + "cv");
      f.seed = static_cast<std::uint64_t>(get_int(t, "field", "seed", w));
      f.correlation_length = get_float(t, "field", "correlation_length", w);
      f.covariance = get_string(t, "field", "covariance", w) == "exponential"
                         ? Field::Covariance::Exponential
                         : Field::Covariance::SquaredExponential;
    }
    return f;
  }

  // A shape (`key = { type = "box", ... }` in table t); `where` names the table ("node_set[0].").
  // With `grid` (the lattice's modules and the case file's folder), also a mask of modules read
  // from a NumPy file (`type = "npy"`).
  struct MaskGrid {
    index_t nx, ny, nz;
    double L;
    std::filesystem::path folder;
  };
  Shape shape(const toml::table& t, const char* key, const std::string& where,
              const MaskGrid* grid = nullptr) const {
    const toml::node* n = t.get(key);
    const std::string name = where + key;
    if (!n || !n->is_table())
      fail(n ? n : &t, name,
           fmt::format("expected a shape, {{ type = \"box\", \"cylinder\", \"sphere\"{}, "
                       "... }}, got {}",
                       grid ? ", \"half_space\", \"npy\" or \"stl\"" : " or \"half_space\"",
                       n ? describe(*n) : "none"));
    const toml::table& st = *n->as_table();
    const std::string w = name + ".";
    check_known(st, "shape", w);
    Shape out;
    const std::string type = get_string(st, "shape", "type", w);
    const std::string what = fmt::format("a \"{}\" shape", type);
    auto vec = [&](const char* k) {
      const auto v = opt_vec3(st, "shape", k, w);
      if (!v)
        fail(&st, w + k, fmt::format("missing: {} needs {}", what, k));
      return *v;
    };
    auto radius = [&] {
      const auto r = opt_float(st, "shape", "radius", w);
      if (!r)
        fail(&st, w + "radius", fmt::format("missing: {} needs radius", what));
      return *r;
    };
    if (type == "box") {
      only(st, w, what, {"type", "min", "max", "axis", "angle"});
      out.type = Shape::Type::Box;
      out.lo = vec("min");
      out.hi = vec("max");
      if (!(out.lo.x <= out.hi.x && out.lo.y <= out.hi.y && out.lo.z <= out.hi.z))
        fail(st.get("max"), w + "max",
             fmt::format("expected a corner at or above min [{:g}, {:g}, {:g}] on every axis, "
                         "got [{:g}, {:g}, {:g}]",
                         out.lo.x, out.lo.y, out.lo.z, out.hi.x, out.hi.y, out.hi.z));
      const auto axis = opt_string(st, "shape", "axis", w);
      const auto angle = opt_float(st, "shape", "angle", w);
      if (axis.has_value() != angle.has_value())
        fail(&st, w + (axis ? "angle" : "axis"),
             axis ? "missing: axis needs angle" : "missing: angle needs axis");
      if (axis) {
        out.axis = (*axis)[0] - 'x';
        out.angle = *angle * std::numbers::pi / 180.0;
      }
    } else if (type == "cylinder") {
      only(st, w, what, {"type", "start", "end", "radius"});
      out.type = Shape::Type::Cylinder;
      out.a = vec("start");
      out.b = vec("end");
      out.radius = radius();
      if (out.a.x == out.b.x && out.a.y == out.b.y && out.a.z == out.b.z)
        fail(st.get("end"), w + "end",
             "expected an end apart from start (the axis), got the same point");
    } else if (type == "npy" || type == "stl") {
      if (!grid)
        fail(st.get("type"), w + "type",
             fmt::format("expected \"box\", \"cylinder\", \"sphere\" or \"half_space\" (a "
                         "mask of modules, \"npy\" or \"stl\", shapes the body only: "
                         "[[geometry]]), got \"{}\"",
                         type));
      const bool stl = type == "stl";
      if (stl)
        only(st, w, what, {"type", "file", "scale"});
      else
        only(st, w, what, {"type", "file"});
      out.type = Shape::Type::Mask;
      const auto file = opt_string(st, "shape", "file", w);
      if (!file)
        fail(&st, w + "file", fmt::format("missing: {} needs file", what));
      std::filesystem::path p(*file);
      if (p.is_relative())
        p = grid->folder / p;
      const double scale = stl ? get_float(st, "shape", "scale", w) : 1.0;
      try {
        out.mask = std::make_shared<const std::vector<std::uint8_t>>(
            stl ? surface_mask(read_stl(p.string(), scale), grid->nx, grid->ny, grid->nz, grid->L,
                               p.string())
                : read_npy_mask(p.string(), grid->nx, grid->ny, grid->nz));
      } catch (const InputError& e) {
        fail(st.get("file"), w + "file", e.what());
      }
      out.file = *file;
      out.scale = scale;
      out.stl = stl;
    } else if (type == "sphere") {
      only(st, w, what, {"type", "centre", "radius"});
      out.type = Shape::Type::Sphere;
      out.a = vec("centre");
      out.radius = radius();
    } else {
      only(st, w, what, {"type", "point", "normal"});
      out.type = Shape::Type::HalfSpace;
      out.a = vec("point");
      out.normal = vec("normal");
      if (out.normal.x == 0.0 && out.normal.y == 0.0 && out.normal.z == 0.0)
        fail(st.get("normal"), w + "normal", "expected a vector that is not zero, got [0, 0, 0]");
    }
    return out;
  }

private:
  std::string file_;
};

} // namespace

namespace {

// A case file's structure (keys, numbers, brackets) is ASCII; other characters belong only in
// strings and comments. Checking this first gives a clear message, and keeps inputs away from
// a path of the TOML parser (toml++ 3.3) that has undefined behaviour on a non-ASCII
// character inside a number.
void check_characters(const std::string& text, const std::string& name) {
  int line = 1;
  enum { Code, Comment, Basic, Literal, MultiBasic, MultiLiteral } state = Code;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    auto starts = [&](const char* w) { return text.compare(i, std::strlen(w), w) == 0; };
    if (c == 0 || (c < 32 && c != '\t' && c != '\n' && c != '\r'))
      throw InputError(fmt::format("{}:{}: malformed TOML: control character (byte {}) in the "
                                   "file",
                                   name, line, static_cast<int>(c)));
    if (c == '\n') {
      ++line;
      if (state == Comment || state == Basic || state == Literal)
        state = Code; // single-line strings end at the line (the parser reports it if open)
      continue;
    }
    switch (state) {
    case Code:
      if (c == '#')
        state = Comment;
      else if (starts("\"\"\"")) {
        state = MultiBasic;
        i += 2;
      } else if (starts("'''")) {
        state = MultiLiteral;
        i += 2;
      } else if (c == '"')
        state = Basic;
      else if (c == '\'')
        state = Literal;
      else if (c > 126)
        throw InputError(fmt::format("{}:{}: malformed TOML: a non-ASCII character outside a "
                                     "string or comment",
                                     name, line));
      break;
    case Basic:
      if (c == '\\')
        ++i;
      else if (c == '"')
        state = Code;
      break;
    case Literal:
      if (c == '\'')
        state = Code;
      break;
    case MultiBasic:
      if (c == '\\')
        ++i;
      else if (starts("\"\"\"")) {
        state = Code;
        i += 2;
      }
      break;
    case MultiLiteral:
      if (starts("'''")) {
        state = Code;
        i += 2;
      }
      break;
    case Comment:
      break;
    }
  }
}

} // namespace

CaseSpec parse_case(const std::string& text, const std::string& name) {
  check_characters(text, name);
  toml::table root;
  try {
    root = toml::parse(text, name);
  } catch (const toml::parse_error& e) {
    throw InputError(
        fmt::format("{}:{}: malformed TOML: {}", name, e.source().begin.line, e.description()));
  }
  CaseSpec c;
  Reader reader(name);
  reader.lines_ = &c.key_lines;
  const Reader& r = reader;
  c.file = name;
  // Top level: only the declared tables.
  for (const auto& [k, node] : root) {
    const std::string key(k.str());
    const bool top = std::any_of(std::begin(kTopTables), std::end(kTopTables),
                                 [&](const char* t) { return key == t; });
    const bool arr = std::any_of(std::begin(kArrayTables), std::end(kArrayTables),
                                 [&](const char* t) { return key == t; });
    if (top && !node.is_table())
      r.fail(&node, key, "expected a table [" + key + "]");
    if (arr && !node.is_array_of_tables())
      r.fail(&node, key, "expected an array of tables [[" + key + "]]");
    if (!top && !arr) {
      std::string best;
      std::size_t best_d = 3;
      for (const char* t : kTopTables)
        if (edit_distance(key, t) < best_d)
          best_d = edit_distance(key, t), best = t;
      for (const char* t : kArrayTables)
        if (edit_distance(key, t) < best_d)
          best_d = edit_distance(key, t), best = t;
      r.fail(&node, key,
             best.empty() ? "unknown table"
                          : fmt::format("unknown table; did you mean \"{}\"?", best));
    }
  }
  auto table = [&](const char* t) -> const toml::table& {
    static const toml::table empty;
    const toml::table* p = root[t].as_table();
    if (p)
      c.key_lines[t] = static_cast<int>(p->source().begin.line);
    return p ? *p : empty;
  };
  // The entries of an array of tables; each entry's line is kept as "name[i]" for errors
  // found once the body is built (a pre-crack that crosses no bar, a node set that is empty).
  auto array = [&](const char* t) {
    std::vector<const toml::table*> out;
    if (const toml::array* a = root[t].as_array())
      for (const toml::node& e : *a) {
        c.key_lines[fmt::format("{}[{}]", t, out.size())] = static_cast<int>(e.source().begin.line);
        out.push_back(e.as_table());
      }
    return out;
  };

  const toml::table& cs = table("case");
  r.check_known(cs, "case", "case.");
  c.title = r.get_string(cs, "case", "title", "case.");

  const toml::table& lat = table("lattice");
  if (!root.contains("lattice"))
    r.fail(nullptr, "lattice", "missing required table [lattice]");
  r.check_known(lat, "lattice", "lattice.");
  {
    const toml::node* n = lat.get("modules");
    if (!n)
      r.fail(&lat, "lattice.modules", "missing required key");
    const toml::array* a = n->as_array();
    if (!a || a->size() != 3 ||
        !std::all_of(a->begin(), a->end(), [](const toml::node& e) { return e.is_integer(); }))
      r.fail(n, "lattice.modules",
             fmt::format("expected 3 integers [nx, ny, nz], got {}", r.describe(*n)));
    index_t m[3];
    for (int i = 0; i < 3; ++i) {
      const auto v = *(*a)[static_cast<std::size_t>(i)].value<std::int64_t>();
      r.check_range(r.decl("lattice", "modules"), n, "lattice.modules", static_cast<double>(v));
      m[i] = static_cast<index_t>(v);
    }
    c.nx = m[0];
    c.ny = m[1];
    c.nz = m[2];
  }
  c.L = r.get_float(lat, "lattice", "L", "lattice.");
  {
    const std::string ps = r.get_string(lat, "lattice", "plane_strain", "lattice.");
    c.plane_strain_axis = ps == "none" ? -1 : ps[0] - 'x';
  }

  const toml::table& mat = table("material");
  if (!root.contains("material"))
    r.fail(nullptr, "material", "missing required table [material]");
  r.check_known(mat, "material", "material.");
  c.law = r.get_string(mat, "material", "law", "material.");
  {
    const toml::table& fat = table("fatigue");
    const bool with_table = root.contains("fatigue");
    if (c.law == "bilinear_fatigue" && !with_table)
      r.fail(mat.get("law"), "material.law",
             "law = \"bilinear_fatigue\" needs a [fatigue] table (A, m; docs/case-format.md)");
    if (c.law != "bilinear_fatigue" && with_table)
      r.fail(&fat, "fatigue",
             fmt::format("a [fatigue] table applies to law = \"bilinear_fatigue\", not \"{}\"",
                         c.law));
    if (with_table) {
      r.check_known(fat, "fatigue", "fatigue.");
      FatigueSpec f;
      f.A = r.get_float(fat, "fatigue", "A", "fatigue.");
      f.m = r.get_float(fat, "fatigue", "m", "fatigue.");
      f.threshold = r.get_float(fat, "fatigue", "threshold", "fatigue.");
      f.gate = r.opt_float(fat, "fatigue", "gate", "fatigue.").value_or(0.0);
      f.length = r.has(fat, "length") ? *r.opt_float(fat, "fatigue", "length", "fatigue.") : c.L;
      f.count_every =
          static_cast<std::uint64_t>(r.get_int(fat, "fatigue", "count_every", "fatigue."));
      f.jump = r.get_bool(fat, "fatigue", "jump", "fatigue.");
      f.jump_window =
          static_cast<std::uint64_t>(r.get_int(fat, "fatigue", "jump_window", "fatigue."));
      f.jump_breaks =
          static_cast<std::uint64_t>(r.get_int(fat, "fatigue", "jump_breaks", "fatigue."));
      f.jump_max = r.get_float(fat, "fatigue", "jump_max", "fatigue.");
      f.jump_fraction = r.get_float(fat, "fatigue", "jump_fraction", "fatigue.");
      const auto lo = r.opt_vec3(fat, "fatigue", "box_min", "fatigue.");
      const auto hi = r.opt_vec3(fat, "fatigue", "box_max", "fatigue.");
      if (lo.has_value() != hi.has_value())
        r.fail(&fat, lo ? "fatigue.box_max" : "fatigue.box_min",
               lo ? "missing: box_min needs box_max" : "missing: box_max needs box_min");
      if (lo) {
        if (!(lo->x <= hi->x && lo->y <= hi->y && lo->z <= hi->z))
          r.fail(fat.get("box_max"), "fatigue.box_max",
                 fmt::format("expected a corner at or above box_min [{:g}, {:g}, {:g}] in x, y "
                             "and z, got [{:g}, {:g}, {:g}]",
                             lo->x, lo->y, lo->z, hi->x, hi->y, hi->z));
        f.box = std::array<Vec3, 2>{*lo, *hi};
      }
      if (!f.jump)
        for (const char* k : {"jump_window", "jump_breaks", "jump_max", "jump_fraction"})
          if (r.has(fat, k))
            r.fail(fat.get(k), std::string("fatigue.") + k, "does not apply without jump = true");
      c.material.fatigue = f;
    }
  }
  const double extent[3] = {c.nx * c.L, c.ny * c.L, c.nz * c.L};
  // A property given as a field keeps a representative value in the MaterialSpec (the mean,
  // or the mean of the grading's values) for the checks and reports made with one number.
  auto property = [&](const char* key, std::optional<Field>& field) -> std::optional<double> {
    field = r.opt_field(mat, key, extent);
    if (!field)
      return r.opt_float(mat, "material", key, "material.");
    if (field->kind == Field::Kind::Weibull)
      return field->mean;
    double sum = 0.0;
    for (const auto& p : field->table)
      sum += p.second;
    return sum / static_cast<double>(field->table.size());
  };
  c.material.E = *property("E", c.fields.E);
  c.material.nu = r.get_float(mat, "material", "nu", "material.");
  c.material.rho = *property("rho", c.fields.rho);
  c.material.Gf = *property("Gf", c.fields.Gf);
  c.material.e_p = property("e_p", c.fields.e_p);
  c.material.R_f = property("R_f", c.fields.R_f);
  c.material.e_r = property("e_r", c.fields.e_r);
  c.material.single_ratio = r.get_bool(mat, "material", "single_ratio", "material.");
  c.material.allow_low_kr = r.get_bool(mat, "material", "allow_low_kr", "material.");
  if (c.material.e_p.has_value() == c.material.R_f.has_value())
    r.fail(&mat, "material.e_p",
           c.material.e_p ? "expected e_p or R_f, not both" : "missing: give e_p or R_f");

  {
    // The body's modules: [[geometry]] add or remove, in order.
    const auto ops = array("geometry");
    const Reader::MaskGrid grid{c.nx, c.ny, c.nz, c.L, std::filesystem::path(name).parent_path()};
    for (std::size_t i = 0; i < ops.size(); ++i) {
      const toml::table& t = *ops[i];
      const std::string w = fmt::format("geometry[{}].", i);
      r.check_known(t, "geometry", w);
      if (r.has(t, "add") == r.has(t, "remove"))
        r.fail(&t, w + "add",
               "expected exactly one of add = { type = ... } or remove = { type = ... }");
      ShapeOp op;
      op.add = r.has(t, "add");
      op.shape = r.shape(t, op.add ? "add" : "remove", w, &grid);
      c.geometry.push_back(std::move(op));
    }
  }

  {
    // Material regions: the properties they give, as numbers or fields, inside their shapes.
    const auto regions = array("region");
    for (std::size_t i = 0; i < regions.size(); ++i) {
      const toml::table& t = *regions[i];
      const std::string w = fmt::format("region[{}].", i);
      r.check_known(t, "region", w);
      RegionSpec rg;
      rg.shape = r.shape(t, "shape", w);
      const std::pair<const char*, std::optional<Field>*> keys[] = {
          {"E", &rg.E},     {"Gf", &rg.Gf},   {"e_p", &rg.e_p},
          {"e_r", &rg.e_r}, {"R_f", &rg.R_f}, {"rho", &rg.rho}};
      for (const auto& [key, field] : keys) {
        *field = r.opt_field(t, key, extent, w);
        if (!*field)
          if (const auto v = r.opt_float(t, "region", key, w))
            *field = Field::constant(*v);
      }
      // The region's properties follow [material]'s rule: e_p or R_f as [material] gives
      // one, and Gf only where e_r is not given (with e_r, Gf follows from it).
      auto refuse = [&](const char* key, const std::string& why) {
        r.fail(t.get(key), w + key, why);
      };
      if (rg.R_f && c.material.e_p)
        refuse("R_f", "[material] gives e_p: give the region's e_p, not R_f");
      if (rg.e_p && c.material.R_f)
        refuse("e_p", "[material] gives R_f: give the region's R_f, not e_p");
      if (rg.e_r && !c.material.e_r)
        refuse("e_r", "[material] gives no e_r (K_r follows from Gf, eq. 12): give the "
                      "region's Gf, not e_r");
      if (rg.Gf && c.material.e_r)
        refuse("Gf", "[material] gives e_r (Gf follows from it, eq. 11): give the region's "
                     "e_r, not Gf");
      if (!rg.E && !rg.Gf && !rg.e_p && !rg.e_r && !rg.R_f && !rg.rho)
        r.fail(&t, w + "shape", "a region gives no property: expected E, Gf, e_p, e_r, R_f or rho");
      c.regions.push_back(std::move(rg));
    }
  }

  std::vector<std::string> set_names;
  const auto sets = array("node_set");
  for (std::size_t i = 0; i < sets.size(); ++i) {
    const toml::table& t = *sets[i];
    const std::string w = fmt::format("node_set[{}].", i);
    r.check_known(t, "node_set", w);
    NodeSetSpec s;
    s.name = r.get_string(t, "node_set", "name", w);
    if (std::find(set_names.begin(), set_names.end(), s.name) != set_names.end())
      r.fail(t.get("name"), w + "name", fmt::format("node set \"{}\" is defined twice", s.name));
    const int ways = r.has(t, "face") + r.has(t, "face_centres") + r.has(t, "box_min") +
                     r.has(t, "shape") + (r.get_bool(t, "node_set", "all", w) ? 1 : 0);
    if (ways != 1)
      r.fail(&t, w + "face",
             fmt::format("expected exactly one of face, face_centres, box_min/box_max, shape, "
                         "all = true; got {}",
                         ways));
    if (auto f = r.opt_string(t, "node_set", "face", w)) {
      s.kind = NodeSetSpec::Kind::Face;
      s.face = parse_face(*f);
    } else if (auto fc = r.opt_string(t, "node_set", "face_centres", w)) {
      s.kind = NodeSetSpec::Kind::FaceCentres;
      s.face = parse_face(*fc);
    } else if (r.has(t, "shape")) {
      s.kind = NodeSetSpec::Kind::Shape;
      s.shape = r.shape(t, "shape", w);
      s.surface = r.get_bool(t, "node_set", "surface", w);
    } else if (r.has(t, "box_min")) {
      s.kind = NodeSetSpec::Kind::Box;
      s.lo = *r.opt_vec3(t, "node_set", "box_min", w);
      const auto hi = r.opt_vec3(t, "node_set", "box_max", w);
      if (!hi)
        r.fail(&t, w + "box_max", "missing: box_min needs box_max");
      s.hi = *hi;
    }
    if (s.kind != NodeSetSpec::Kind::Shape && r.get_bool(t, "node_set", "surface", w))
      r.fail(t.get("surface"), w + "surface",
             "surface = true applies to a node set given by shape (the body's surface inside it)");
    set_names.push_back(s.name);
    c.node_sets.push_back(s);
  }
  auto known_set = [&](const toml::table& t, const std::string& w) {
    const std::string set = *r.opt_string(t, "fixed", "set", w);
    if (std::find(set_names.begin(), set_names.end(), set) == set_names.end())
      r.fail(t.get("set"), w + "set",
             fmt::format("expected the name of a [[node_set]], got \"{}\"", set));
    return set;
  };

  const auto fixed = array("fixed");
  for (std::size_t i = 0; i < fixed.size(); ++i) {
    const std::string w = fmt::format("fixed[{}].", i);
    r.check_known(*fixed[i], "fixed", w);
    c.fixed.push_back({known_set(*fixed[i], w), r.dofs(*fixed[i], "fixed", w)});
  }
  const auto vel = array("velocity");
  // The control tables read, checked against the probes once they are read.
  std::vector<std::pair<const toml::table*, std::string>> controls;
  for (std::size_t i = 0; i < vel.size(); ++i) {
    const toml::table& t = *vel[i];
    const std::string w = fmt::format("velocity[{}].", i);
    r.check_known(t, "velocity", w);
    VelocitySpec v;
    v.set = known_set(t, w);
    v.dofs = r.dofs(t, "velocity", w);
    v.value = *r.opt_vec3(t, "velocity", "value", w);
    const auto ramp = r.opt_float(t, "velocity", "ramp", w);
    if (ramp && t.contains("function"))
      r.fail(t.get("ramp"), w + "ramp", "expected ramp or function, not both");
    v.scale = ramp ? TimeFunction({LinearRamp{1.0, *ramp}}) : r.function(t, w);
    if (const toml::node* cn = t.get("control")) {
      const toml::table* ct = cn->as_table();
      const std::string cw = w + "control.";
      if (!ct)
        r.fail(cn, w + "control",
               fmt::format("expected a table {{ probe = \"<gauge probe>\", rate = ... }}, got {}",
                           r.describe(*cn)));
      r.check_known(*ct, "control", cw);
      for (const char* k : {"ramp", "function"})
        if (t.contains(k))
          r.fail(t.get(k), w + k,
                 "does not apply to a controlled velocity (its controller sets the factor on "
                 "value; control.rate gives the probe's rate)");
      const double speed = std::sqrt(v.value.x * v.value.x + v.value.y * v.value.y +
                                     v.value.z * v.value.z);
      if (!(speed > 0.0))
        r.fail(t.get("value"), w + "value",
               "expected a velocity that is not zero for a controlled velocity (its direction "
               "and the fastest the controller may drive the set), got [0, 0, 0]");
      ControlSpec control;
      control.probe = r.get_string(*ct, "control", "probe", cw);
      control.rate = r.get_float(*ct, "control", "rate", cw);
      if (control.rate == 0.0)
        r.fail(ct->get("rate"), cw + "rate",
               "expected a rate that is not 0 (the probe's target is rate * t)");
      control.response_time = r.opt_float(*ct, "control", "response_time", cw).value_or(0.0);
      v.control = control;
      controls.push_back({ct, cw});
    }
    c.velocities.push_back(v);
  }
  const auto loads = array("load");
  for (std::size_t i = 0; i < loads.size(); ++i) {
    const toml::table& t = *loads[i];
    const std::string w = fmt::format("load[{}].", i);
    r.check_known(t, "load", w);
    // One of the four ways to give the force, in LoadSpec::Kind's order.
    static const char* const kinds[] = {"force", "traction", "total", "acceleration"};
    std::optional<Vec3> given;
    LoadSpec::Kind kind = LoadSpec::Kind::Force;
    for (int k = 0; k < 4; ++k)
      if (const auto v = r.opt_vec3(t, "load", kinds[k], w)) {
        if (given)
          r.fail(t.get(kinds[k]), w + kinds[k],
                 fmt::format("expected one of force, traction, total and acceleration, got {} "
                             "and {}",
                             kinds[static_cast<int>(kind)], kinds[k]));
        given = v;
        kind = static_cast<LoadSpec::Kind>(k);
      }
    if (!given)
      r.fail(&t, w + "force",
             "expected force (N on each node), traction (Pa on a surface), total (N over a "
             "surface) or acceleration (m/s^2 on each node's mass)");
    c.loads.push_back(
        {r.get_string(t, "load", "name", w), known_set(t, w), kind, *given, r.function(t, w)});
  }
  const auto platens = array("platen");
  for (std::size_t i = 0; i < platens.size(); ++i) {
    const toml::table& t = *platens[i];
    const std::string w = fmt::format("platen[{}].", i);
    r.check_known(t, "platen", w);
    PlatenSpec p;
    p.name = r.get_string(t, "platen", "name", w);
    for (const PlatenSpec& q : c.platens)
      if (q.name == p.name)
        r.fail(t.get("name"), w + "name",
               fmt::format("expected a name no other platen has, got \"{}\" again", p.name));
    const std::string shape = r.get_string(t, "platen", "shape", w);
    p.kind = shape == "cylinder" ? Platen::Kind::Cylinder : Platen::Kind::Plane;
    const char* along = p.kind == Platen::Kind::Plane ? "normal" : "axis";
    if (p.kind == Platen::Kind::Plane)
      r.only(t, w, "a \"plane\" platen",
             {"name", "shape", "point", "normal", "velocity", "ramp", "function", "friction",
              "penalty"});
    else
      r.only(t, w, "a \"cylinder\" platen",
             {"name", "shape", "point", "axis", "radius", "velocity", "ramp", "function",
              "friction", "penalty"});
    const auto point = r.opt_vec3(t, "platen", "point", w);
    if (!point)
      r.fail(&t, w + "point",
             fmt::format("missing: a {} platen needs point = [x, y, z] ({})", shape,
                         p.kind == Platen::Kind::Plane ? "a point of its face"
                                                       : "a point of its axis"));
    p.point = *point;
    const auto dir = r.opt_vec3(t, "platen", along, w);
    const double len = dir ? std::sqrt(dir->x * dir->x + dir->y * dir->y + dir->z * dir->z) : 0.0;
    if (!(len > 0.0) || !std::isfinite(len))
      r.fail(dir ? t.get(along) : &t, w + along,
             dir ? fmt::format("expected a vector that is not zero, got [{}, {}, {}]", dir->x,
                               dir->y, dir->z)
                 : fmt::format("missing: a {} platen needs {} = [x, y, z] ({})", shape, along,
                               p.kind == Platen::Kind::Plane
                                   ? "its normal, pointing from the platen towards the body"
                                   : "the direction of its axis"));
    p.direction = {dir->x / len, dir->y / len, dir->z / len};
    if (p.kind == Platen::Kind::Cylinder) {
      const auto radius = r.opt_float(t, "platen", "radius", w);
      if (!radius)
        r.fail(&t, w + "radius", "missing: a cylinder platen needs radius (m)");
      p.radius = *radius;
    }
    p.velocity = r.opt_vec3(t, "platen", "velocity", w).value_or(Vec3{});
    const auto ramp = r.opt_float(t, "platen", "ramp", w);
    if (ramp && t.contains("function"))
      r.fail(t.get("ramp"), w + "ramp", "expected ramp or function, not both");
    p.scale = ramp ? TimeFunction({LinearRamp{1.0, *ramp}}) : r.function(t, w);
    p.friction = r.get_float(t, "platen", "friction", w);
    p.penalty = r.get_float(t, "platen", "penalty", w);
    c.platens.push_back(p);
  }
  const auto cracks = array("precrack");
  for (std::size_t i = 0; i < cracks.size(); ++i) {
    const toml::table& t = *cracks[i];
    const std::string w = fmt::format("precrack[{}].", i);
    r.check_known(t, "precrack", w);
    c.precracks.push_back(
        {{r.get_string(t, "precrack", "name", w), *r.opt_vec3(t, "precrack", "origin", w),
          *r.opt_vec3(t, "precrack", "edge1", w), *r.opt_vec3(t, "precrack", "edge2", w)},
         r.get_bool(t, "precrack", "nudge", w)});
  }

  const toml::table& time = table("time");
  if (!root.contains("time"))
    r.fail(nullptr, "time", "missing required table [time]");
  r.check_known(time, "time", "time.");
  c.end_time = r.get_float(time, "time", "end", "time.");
  c.stop_displacement = r.opt_float(time, "time", "stop_displacement", "time.").value_or(0.0);
  const std::string rule = r.get_string(time, "time", "rule", "time.");
  c.step.rule = rule == "dt"      ? TimeStep::Rule::Given
                : rule == "paper" ? TimeStep::Rule::Paper
                                  : TimeStep::Rule::Safety;
  c.step.safety = r.get_float(time, "time", "safety", "time.");
  c.step.courant = r.get_float(time, "time", "courant", "time.");
  if (time.contains("safety") && c.step.rule != TimeStep::Rule::Safety)
    r.fail(time.get("safety"), "time.safety",
           fmt::format("does not apply to rule = \"{}\" (safety is rule = \"safety\"'s)", rule));
  if (time.contains("courant") && c.step.rule != TimeStep::Rule::Paper)
    r.fail(time.get("courant"), "time.courant",
           fmt::format("does not apply to rule = \"{}\" (courant is rule = \"paper\"'s)", rule));
  if (const auto dt = r.opt_float(time, "time", "dt", "time.")) {
    if (c.step.rule != TimeStep::Rule::Given)
      r.fail(time.get("dt"), "time.dt", "given, but rule is not \"dt\"; set rule = \"dt\"");
    c.step.dt = *dt;
  } else if (c.step.rule == TimeStep::Rule::Given) {
    r.fail(&time, "time.dt", "missing: rule = \"dt\" needs dt");
  }
  c.damping = r.get_float(time, "time", "damping", "time.");

  const toml::table& out = table("output");
  r.check_known(out, "output", "output.");
  c.output.energy_every =
      static_cast<std::uint64_t>(r.get_int(out, "output", "energy_every", "output."));
  c.output.vtu_every = static_cast<std::uint64_t>(r.get_int(out, "output", "vtu_every", "output."));
  c.output.vtu = r.get_bool(out, "output", "vtu", "output.");
  c.output.plots = r.get_bool(out, "output", "plots", "output.");
  c.output.checkpoint_every =
      static_cast<std::uint64_t>(r.get_int(out, "output", "checkpoint_every", "output."));
  c.output.checkpoint_seconds = r.get_float(out, "output", "checkpoint_seconds", "output.");
  c.output.end_checkpoint = r.get_bool(out, "output", "end_checkpoint", "output.");
  c.output.vtu_zlib = r.get_string(out, "output", "vtu_compression", "output.") == "zlib";
  if (const toml::node* a = out.get("vtu_arrays")) {
    const toml::array* arr = a->as_array();
    if (!arr || arr->empty())
      r.fail(a, "output.vtu_arrays",
             fmt::format("expected a list of array names, got {}", r.describe(*a)));
    for (const toml::node& e : *arr) {
      if (!e.is_string())
        r.fail(&e, "output.vtu_arrays",
               fmt::format("expected array names (strings), got {}", r.describe(e)));
      c.output.vtu_arrays.push_back(*e.value<std::string>());
    }
  }

  const toml::table& an = table("analysis");
  r.check_known(an, "analysis", "analysis.");
  c.analysis.crack = r.get_bool(an, "analysis", "crack", "analysis.");
  c.analysis.min_branch_length =
      r.opt_float(an, "analysis", "min_branch_length", "analysis.").value_or(0.0);
  c.analysis.branch_fit_length =
      r.opt_float(an, "analysis", "branch_fit_length", "analysis.").value_or(0.0);
  c.analysis.speed_window = r.opt_float(an, "analysis", "speed_window", "analysis.").value_or(0.0);
  c.analysis.speed_fit_length =
      r.opt_float(an, "analysis", "speed_fit_length", "analysis.").value_or(0.0);
  c.analysis.zone_flag_length =
      r.opt_float(an, "analysis", "zone_flag_length", "analysis.").value_or(0.0);
  c.analysis.fatigue = r.get_bool(an, "analysis", "fatigue", "analysis.");
  c.analysis.fatigue_load = r.opt_string(an, "analysis", "fatigue_load", "analysis.").value_or("");
  c.analysis.fatigue_points = r.get_int(an, "analysis", "fatigue_points", "analysis.");
  c.analysis.fatigue_window = r.get_string(an, "analysis", "fatigue_window", "analysis.");
  c.analysis.fatigue_rate = r.get_string(an, "analysis", "fatigue_rate", "analysis.");
  c.analysis.fatigue_fit_after = r.get_float(an, "analysis", "fatigue_fit_after", "analysis.");
  c.analysis.fatigue_fit_elastic = r.get_bool(an, "analysis", "fatigue_fit_elastic", "analysis.");
  c.analysis.fatigue_band = r.opt_float(an, "analysis", "fatigue_band", "analysis.").value_or(0.0);
  c.analysis.fatigue_unstable_advance =
      r.opt_float(an, "analysis", "fatigue_unstable_advance", "analysis.").value_or(0.0);
  c.analysis.fatigue_width =
      r.opt_float(an, "analysis", "fatigue_width", "analysis.").value_or(0.0);
  // The analyses measure the crack from a pre-crack and the cycles of a load: refuse a case
  // they cannot analyse before it runs.
  for (const auto& [on, key] :
       {std::pair{c.analysis.crack, "crack"}, std::pair{c.analysis.fatigue, "fatigue"}})
    if (on && c.precracks.empty())
      r.fail(an.get(key), std::string("analysis.") + key,
             "expected a case with a [[precrack]] (the analysis measures the crack from it), "
             "got none");
  if (c.analysis.fatigue) {
    auto has_sine = [](const LoadSpec& l) {
      for (const TimeTerm& term : l.scale.terms())
        if (std::holds_alternative<GrowingSine>(term))
          return true;
      return false;
    };
    const LoadSpec* chosen = nullptr;
    for (const LoadSpec& l : c.loads)
      if (c.analysis.fatigue_load.empty() ? has_sine(l) : l.name == c.analysis.fatigue_load) {
        chosen = &l;
        break;
      }
    if (!c.analysis.fatigue_load.empty() && !chosen)
      r.fail(an.get("fatigue_load"), "analysis.fatigue_load",
             fmt::format("expected the name of a [[load]], got \"{}\"", c.analysis.fatigue_load));
    if (!chosen || !has_sine(*chosen))
      r.fail(an.get("fatigue"), "analysis.fatigue",
             "expected a [[load]] whose function has a \"growing_sine\" term (its cycles are "
             "counted), got none");
    if (chosen && chosen->kind == LoadSpec::Kind::Acceleration)
      r.fail(an.get(c.analysis.fatigue_load.empty() ? "fatigue" : "fatigue_load"),
             c.analysis.fatigue_load.empty() ? "analysis.fatigue" : "analysis.fatigue_load",
             fmt::format("expected a load on a face, whose remote stress is known, got \"{}\", "
                         "a body force (acceleration)",
                         chosen->name));
  }

  std::vector<std::string> load_names;
  for (const LoadSpec& l : c.loads)
    load_names.push_back(l.name);
  const auto probes = array("probe");
  for (std::size_t i = 0; i < probes.size(); ++i) {
    const toml::table& t = *probes[i];
    const std::string w = fmt::format("probe[{}].", i);
    r.check_known(t, "probe", w);
    ProbeSpec p;
    p.name = r.get_string(t, "probe", "name", w);
    for (const ProbeSpec& q : c.probes) // each names a column of probes.csv
      if (q.name == p.name)
        r.fail(t.get("name"), w + "name",
               fmt::format("expected a name no other probe has (a column of probes.csv); got "
                           "\"{}\" again",
                           p.name));
    const std::string kind = r.get_string(t, "probe", "kind", w);
    const std::string what = fmt::format("{} \"{}\" probe", kind[0] == 'o' ? "an" : "a", kind);
    if (kind == "bar_force")
      r.only(t, w, what, {"name", "kind", "at"});
    else if (kind == "reaction")
      r.only(t, w, what, {"name", "kind", "set", "component"});
    else if (kind == "displacement")
      r.only(t, w, what, {"name", "kind", "at", "set", "component"});
    else if (kind == "opening")
      r.only(t, w, what, {"name", "kind", "from", "from_set", "to", "to_set", "component"});
    else if (kind == "strain")
      r.only(t, w, what, {"name", "kind", "from", "from_set", "to", "to_set"});
    else if (kind == "platen" || kind == "platen_displacement")
      r.only(t, w, what, {"name", "kind", "platen", "component"});
    else
      r.only(t, w, what, {"name", "kind", "load"});
    // A gauge's end (a displacement's node): a point or a node set, one of the two.
    const auto end = [&](const char* point, const char* set) {
      ProbeSpec::End e;
      e.point = r.opt_vec3(t, "probe", point, w);
      const auto named = r.opt_string(t, "probe", set, w);
      if (e.point.has_value() == named.has_value())
        r.fail(named && e.point ? t.get(set) : &t, w + (named && e.point ? set : point),
               fmt::format("expected either {} = [x, y, z] or {} = \"<node set>\" for {}, got {}",
                           point, set, what, named ? "both" : "neither"));
      if (named) {
        if (std::find(set_names.begin(), set_names.end(), *named) == set_names.end())
          r.fail(t.get(set), w + set,
                 fmt::format("expected the name of a [[node_set]], got \"{}\"", *named));
        e.set = *named;
      }
      return e;
    };
    if (kind == "displacement") {
      p.kind = ProbeSpec::Kind::Displacement;
      const ProbeSpec::End e = end("at", "set");
      p.has_at = e.point.has_value();
      p.at = e.point.value_or(Vec3{});
      p.set = e.set;
      p.component = r.get_string(t, "probe", "component", w)[0] - 'x';
    } else if (kind == "opening" || kind == "strain") {
      p.kind = kind == "opening" ? ProbeSpec::Kind::Opening : ProbeSpec::Kind::Strain;
      p.from = end("from", "from_set");
      p.to = end("to", "to_set");
      if (kind == "opening")
        p.component = r.get_string(t, "probe", "component", w)[0] - 'x';
    } else if (kind == "bar_force") {
      p.kind = ProbeSpec::Kind::BarForce;
      const auto at = r.opt_vec3(t, "probe", "at", w);
      if (!at)
        r.fail(&t, w + "at", "missing: a bar_force probe needs at = [x, y, z]");
      p.at = *at;
    } else if (kind == "reaction") {
      p.kind = ProbeSpec::Kind::Reaction;
      if (!t.contains("set"))
        r.fail(&t, w + "set", "missing: a reaction probe needs set");
      p.set = known_set(t, w);
      p.component = r.get_string(t, "probe", "component", w)[0] - 'x';
    } else if (kind == "platen" || kind == "platen_displacement") {
      p.kind = kind == "platen" ? ProbeSpec::Kind::Platen : ProbeSpec::Kind::PlatenDisplacement;
      const auto named = r.opt_string(t, "probe", "platen", w);
      if (!named || std::none_of(c.platens.begin(), c.platens.end(),
                                 [&](const PlatenSpec& q) { return q.name == *named; }))
        r.fail(t.get("platen") ? t.get("platen") : &t, w + "platen",
               fmt::format("expected the name of a [[platen]], got {}",
                           named ? "\"" + *named + "\"" : "nothing"));
      p.platen = *named;
      p.component = r.get_string(t, "probe", "component", w)[0] - 'x';
    } else {
      p.kind = ProbeSpec::Kind::Load;
      const auto l = r.opt_string(t, "probe", "load", w);
      if (!l || std::find(load_names.begin(), load_names.end(), *l) == load_names.end())
        r.fail(t.get("load") ? t.get("load") : &t, w + "load",
               fmt::format("expected the name of a [[load]], got {}",
                           l ? "\"" + *l + "\"" : "nothing"));
      p.load = *l;
    }
    c.probes.push_back(p);
  }
  // A controlled velocity's probe: a gauge (its value starts at 0, as the target rate * t does).
  std::size_t next_control = 0;
  for (VelocitySpec& v : c.velocities) {
    if (!v.control)
      continue;
    const auto& [ct, cw] = controls[next_control++];
    const auto p = std::find_if(c.probes.begin(), c.probes.end(),
                                [&](const ProbeSpec& q) { return q.name == v.control->probe; });
    if (p == c.probes.end())
      r.fail(ct->get("probe"), cw + "probe",
             fmt::format("expected the name of a [[probe]], got \"{}\"", v.control->probe));
    if (p->kind != ProbeSpec::Kind::Displacement && p->kind != ProbeSpec::Kind::Opening &&
        p->kind != ProbeSpec::Kind::Strain)
      r.fail(ct->get("probe"), cw + "probe",
             fmt::format("expected a displacement, opening or strain probe (a gauge), got \"{}\", "
                         "a probe of a force",
                         v.control->probe));
  }
  return c;
}

CaseSpec read_case(const std::string& path) {
  return parse_case(read_text_file(path, "the case file"), path);
}

} // namespace ldem
