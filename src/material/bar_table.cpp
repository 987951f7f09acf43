#include "material/bar_table.hpp"

#include "material/elastic_equivalence.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

namespace ldem {

namespace {

void require(bool ok, const std::string& key, const std::string& expected, double got) {
  if (!ok)
    throw InputError(fmt::format("material.{}: expected {}, got {:g}", key, expected, got));
}

} // namespace

double BarTable::area_ratio(BarKind kind) const {
  if (spec_.single_ratio)
    return kPaperSingleRatio;
  const ElasticEquivalence eq = elastic_equivalence(spec_.nu);
  return kind == BarKind::Normal ? kFractureAreaNormal / eq.area_normal
                                 : kFractureAreaDiag / eq.area_diag;
}

BarTable::BarTable(const Lattice& lat, const MaterialSpec& spec, const BarFields& fields,
                   const BodyWindow* window)
    : spec_(spec) {
  // The body's number of a bar (messages) and whether the summary counts it.
  auto body_bar = [&](index_t b) { return window ? window->body_bar(b) : b; };
  auto counted = [&](index_t b) { return !window || window->counted(b); };
  require(spec.E > 0 && std::isfinite(spec.E), "E", "a positive modulus in Pa", spec.E);
  require(spec.rho > 0 && std::isfinite(spec.rho), "rho", "a positive density in kg/m^3", spec.rho);
  require(spec.Gf > 0 && std::isfinite(spec.Gf), "Gf", "a positive fracture energy in N/m",
          spec.Gf);
  require(spec.nu > 0.0 && spec.nu < 0.5, "nu", "a Poisson ratio in (0, 0.5)", spec.nu);
  if (spec.e_p.has_value() == spec.R_f.has_value())
    throw InputError("material: give exactly one of e_p (strain at peak force) and R_f "
                     "(failure factor, eq. 7)");
  if (spec.R_f)
    require(*spec.R_f > 0, "R_f", "a positive failure factor", *spec.R_f);
  const double e_p = spec.e_p ? *spec.e_p : failure_strain(*spec.R_f, spec.Gf, spec.E, spec.nu);
  require(e_p > 0 && std::isfinite(e_p), spec.e_p ? "e_p" : "R_f", "a positive peak strain", e_p);
  if (spec.e_r)
    require(*spec.e_r > e_p, "e_r", fmt::format("a rupture strain above e_p = {:g}", e_p),
            *spec.e_r);

  if (spec.nu != 0.25)
    warnings_.push_back(fmt::format(
        "material.nu = {:g}: the cubic lattice is isotropic only for nu = 0.25; with other values "
        "it keeps E and nu along the cube axes but its shear modulus differs from E / (2 (1 + nu))",
        spec.nu));
  const ElasticEquivalence eq = elastic_equivalence(spec.nu);
  const double L = lat.L();
  const double ratio_n = area_ratio(BarKind::Normal), ratio_d = area_ratio(BarKind::Diagonal);
  const double l_n = L, l_d = std::sqrt(3.0) / 2.0 * L;
  // With e_r given, the normal bars' K_r fixes an effective Gf from which the diagonals'
  // K_r follows (eq. 12), so both kinds dissipate in the same proportion to their A^f.
  const double Gf_eff =
      spec.e_r ? (*spec.e_r / e_p) * spec.E * e_p * e_p * l_n / (2.0 * ratio_n) : spec.Gf;
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fi = lat.family(f);
    FamilyMaterial& m = families_[f];
    const bool normal = fi.kind == BarKind::Normal;
    m.l0 = fi.l0;
    m.area = (normal ? eq.area_normal : eq.area_diag) * L * L;
    m.area_f = (normal ? kFractureAreaNormal : kFractureAreaDiag) * L * L;
    m.k = spec.E * m.area / m.l0;
    m.e_p = e_p;
    m.e_r = ductility(Gf_eff, spec.E, e_p, normal ? ratio_n : ratio_d, m.l0) * e_p;
  }

  const std::uint64_t nb = lat.num_bars();
  if (!fields.rho.empty()) {
    if (fields.rho.size() != lat.num_modules())
      throw InputError(fmt::format("material fields: expected one density per module ({}), got {}",
                                   lat.num_modules(), fields.rho.size()));
    for (double r : fields.rho)
      if (!(r > 0.0) || !std::isfinite(r))
        throw InputError(fmt::format("material.rho: the field gives a density {:g}; expected "
                                     "positive values",
                                     r));
    rho_ = fields.rho;
  }
  for (const auto* v : {&fields.E, &fields.Gf, &fields.e_p, &fields.e_r, &fields.R_f})
    if (!v->empty() && v->size() != nb)
      throw InputError(
          fmt::format("material fields: expected one value per bar ({}), got {}", nb, v->size()));
  // A shaped body of one material keeps its constants per family: the step takes its area
  // factors from a byte per bar (StepLayout::bar_code) and never changes the state of its
  // absent bars. One with a fatigue life keeps them per bar (the cycle count reads no codes):
  // its absent bars have no stiffness and strengths no strain reaches.
  const bool varies = !fields.E.empty() || !fields.Gf.empty() || !fields.e_p.empty() ||
                      !fields.e_r.empty() || !fields.R_f.empty() ||
                      (lat.shaped() && spec.fatigue.has_value());
  const bool er_given = spec.e_r.has_value() || !fields.e_r.empty();
  ranges_.rule = fmt::format(
      "e_p {}; {}", spec.e_p || !fields.e_p.empty() ? "given" : "from R_f and Gf (eq. 7)",
      er_given ? "e_r given (normal bars), Gf follows from eq. 11, diagonals' e_r by eq. 12"
               : "K_r from eq. 12 with each bar's Gf, e_r = K_r e_p");
  auto widen = [](double(&r)[2], double v) {
    r[0] = std::min(r[0], v);
    r[1] = std::max(r[1], v);
  };
  for (double* r : {ranges_.E, ranges_.Gf, ranges_.e_p, ranges_.e_r_normal, ranges_.rho}) {
    r[0] = INFINITY;
    r[1] = -INFINITY;
  }
  widen(ranges_.rho, spec.rho);
  if (!rho_.empty()) {
    ranges_.rho[0] = *std::min_element(rho_.begin(), rho_.end());
    ranges_.rho[1] = *std::max_element(rho_.begin(), rho_.end());
  }
  DuctilitySummary& s = summary_;
  bool any_below = false; // some bar of the table has K_r < 1, counted or not
  s.kr_min_normal = s.kr_min_diag = s.worst_kr = s.L_cr_min = INFINITY;
  s.kr_max_normal = s.kr_max_diag = 0.0;
  auto account = [&](index_t bar, BarKind kind, double kr, double L_cr) {
    double& lo = kind == BarKind::Normal ? s.kr_min_normal : s.kr_min_diag;
    double& hi = kind == BarKind::Normal ? s.kr_max_normal : s.kr_max_diag;
    lo = std::min(lo, kr);
    hi = std::max(hi, kr);
    s.L_cr_min = std::min(s.L_cr_min, L_cr);
    if (kr < s.worst_kr) {
      s.worst_kr = kr;
      s.worst_bar = bar;
    }
  };
  if (!varies) {
    widen(ranges_.E, spec.E);
    widen(ranges_.Gf, Gf_eff);
    widen(ranges_.e_p, e_p);
    widen(ranges_.e_r_normal, families_[static_cast<int>(Family::EdgeX)].e_r);
    for (int f = 0; f < kFamilies; ++f) {
      const FamilyInfo& fi = lat.family(f);
      if (fi.count() == 0)
        continue;
      const FamilyMaterial& m = families_[f];
      const double kr = m.e_r / m.e_p;
      any_below |= kr < 1.0;
      // (The first bar of the family: in a window, the first process's is the body's.)
      account(body_bar(fi.offset), fi.kind, kr, critical_length(Gf_eff, spec.E, e_p, ratio_n));
      if (kr < 1.0)
        for (index_t b = fi.offset; b < fi.offset + fi.count(); ++b)
          s.bars_below_one += counted(b) && lat.bar_present(b);
    }
  } else {
    k_.resize(nb);
    e_p_.resize(nb);
    e_r_.resize(nb);
    const double er_scale_d =
        ductility(1.0, 1.0, 1.0, ratio_d, l_d) / ductility(1.0, 1.0, 1.0, ratio_n, l_n);
    for (index_t b = 0; b < nb; ++b) {
      const BarAddress a = lat.bar_address(b);
      const FamilyMaterial& m = families_[static_cast<int>(a.family)];
      const BarKind kind = lat.family(a.family).kind;
      const double factor = lat.area_factor(a.family, a.i, a.j, a.k);
      if (factor == 0.0) {
        // A bar of no present module: no stiffness, and strengths no strain reaches, so that
        // it never changes state (its nodes may be absent ones, which stay where they are).
        k_[b] = 0.0;
        e_p_[b] = kAbsentBarStrain;
        e_r_[b] = 2.0 * kAbsentBarStrain;
        continue;
      }
      const double E = fields.E.empty() ? spec.E : fields.E[b];
      const double Gf_in = fields.Gf.empty() ? spec.Gf : fields.Gf[b];
      double ep = e_p;
      if (!fields.e_p.empty())
        ep = fields.e_p[b];
      else if (!spec.e_p)
        ep = failure_strain(fields.R_f.empty() ? *spec.R_f : fields.R_f[b], Gf_in, E, spec.nu);
      if (!(E > 0 && Gf_in > 0 && ep > 0))
        throw InputError(fmt::format("material fields: bar {} has E = {:g}, Gf = {:g}, e_p = {:g}; "
                                     "expected all positive",
                                     body_bar(b), E, Gf_in, ep));
      const double ratio = kind == BarKind::Normal ? ratio_n : ratio_d;
      k_[b] = E * m.area / m.l0 * factor;
      e_p_[b] = ep;
      double Gf = Gf_in;
      if (er_given) {
        const double er_n = fields.e_r.empty() ? *spec.e_r : fields.e_r[b];
        if (!(er_n > ep))
          throw InputError(fmt::format("material: bar {} has e_r = {:g} <= e_p = {:g}; expected "
                                       "e_r > e_p",
                                       body_bar(b), er_n, ep));
        e_r_[b] = er_n * (kind == BarKind::Normal ? 1.0 : er_scale_d);
        Gf = (er_n / ep) * E * ep * ep * l_n / (2.0 * ratio_n); // eq. 11 for a normal bar
      } else {
        e_r_[b] = ductility(Gf, E, ep, ratio, m.l0) * ep;
      }
      any_below |= e_r_[b] / ep < 1.0;
      if (!counted(b))
        continue;
      if (kind == BarKind::Normal)
        widen(ranges_.e_r_normal, e_r_[b]);
      widen(ranges_.E, E);
      widen(ranges_.Gf, Gf);
      widen(ranges_.e_p, ep);
      const double kr = e_r_[b] / ep;
      account(body_bar(b), kind, kr, critical_length(Gf, E, ep, ratio_n));
      if (kr < 1.0)
        ++s.bars_below_one;
    }
  }
  if (!k_.empty()) {
    // The rows whose bars share one E: E A / l0 as k_ has it before the area factor.
    std::size_t rows = 0;
    for (int f = 0; f < kFamilies; ++f) {
      row_first_[static_cast<std::size_t>(f)] = rows;
      row_nj_[static_cast<std::size_t>(f)] = lat.family(f).nj;
      rows += static_cast<std::size_t>(lat.family(f).nj * lat.family(f).nk);
    }
    row_k_.assign(rows, 0.0);
    for (int f = 0; f < kFamilies && !lat.shaped(); ++f) {
      const FamilyInfo& fi = lat.family(f);
      const FamilyMaterial& m = families_[f];
      for (index_t k = 0; k < fi.nk; ++k)
        for (index_t j = 0; j < fi.nj; ++j) {
          const index_t b0 = fi.offset + fi.ni * (j + fi.nj * k);
          bool same = true;
          for (index_t i = 1; i < fi.ni && same && !fields.E.empty(); ++i)
            same = fields.E[b0 + i] == fields.E[b0];
          const double E = fields.E.empty() ? spec.E : fields.E[b0];
          if (same && fi.ni > 0)
            row_k_[row_first_[static_cast<std::size_t>(f)] +
                   static_cast<std::size_t>(j + fi.nj * k)] = E * m.area / m.l0;
        }
    }
  }
  if (any_below && spec.allow_low_kr) {
    // A brittle bar: e_r just above e_p (the law needs e_r > e_p), force to zero at the peak.
    auto brittle = [&](double& er, double ep) { er = std::max(er, ep * (1.0 + 1e-9)); };
    for (int f = 0; f < kFamilies; ++f)
      brittle(families_[f].e_r, families_[f].e_p);
    for (std::size_t b = 0; b < e_r_.size(); ++b)
      brittle(e_r_[b], e_p_[b]);
  }
  if (!window)
    if (auto warning = check_ductility(s, spec, nb, lat.bar_centre(s.worst_bar), L))
      warnings_.push_back(*warning);
}

std::optional<std::string> check_ductility(const DuctilitySummary& s, const MaterialSpec& spec,
                                           std::uint64_t bars, Vec3 c, double L) {
  if (s.bars_below_one == 0)
    return std::nullopt;
  if (spec.allow_low_kr)
    return fmt::format(
        "material: K_r < 1 in {} bars (smallest {:.4g}), allowed by allow_low_kr: these bars break "
        "at e_p without softening and dissipate EA e_p^2 l0 / 2, more than Gf A^f (L_cr = {:.4g} "
        "m, L = {:.4g} m)",
        s.bars_below_one, s.worst_kr, s.L_cr_min, L);
  throw InputError(fmt::format(
      "material: K_r = e_r / e_p < 1 in {} of {} bars (smallest K_r = {:.4g}, bar {} centred at "
      "({:g}, {:g}, {:g}) m): their rupture strain would lie below their peak strain, a "
      "snap-back in strain that the bar law cannot follow (its softening slope, -EA / (K_r - 1), "
      "is steeper than the elastic one already for K_r < 2 and reverses below 1). The critical "
      "length (eq. 13) is L_cr = {:.4g} m against "
      "L = {:.4g} m: use modules with L <= L_cr, a larger Gf or a smaller e_p, or set "
      "allow_low_kr = true to run anyway",
      s.bars_below_one, bars, s.worst_kr, s.worst_bar, c.x, c.y, c.z, s.L_cr_min, L));
}

BarTable::Properties BarTable::properties(const Lattice& lat, index_t bar) const {
  const BarAddress a = lat.bar_address(bar);
  const FamilyMaterial& m = families_[static_cast<int>(a.family)];
  const double factor = lat.area_factor(a.family, a.i, a.j, a.k);
  if (factor == 0.0)
    return {0.0, 0.0, 0.0, 0.0}; // an absent bar of a shaped body
  const BilinearLaw l = law(lat, bar);
  const double EA = axial_stiffness(lat, bar);
  return {EA / (m.area * factor), 0.5 * EA * l.e_p * l.e_r * m.l0 / (m.area_f * factor), l.e_p,
          l.e_r};
}

double BarTable::row_stiffness(int family, index_t j, index_t k) const {
  if (!per_bar())
    return families_[family].k;
  const auto f = static_cast<std::size_t>(family);
  return row_k_[row_first_[f] + static_cast<std::size_t>(j) +
                static_cast<std::size_t>(row_nj_[f]) * static_cast<std::size_t>(k)];
}

BilinearLaw BarTable::law(const Lattice& lat, index_t bar) const {
  if (per_bar())
    return {e_p_[bar], e_r_[bar]};
  const FamilyMaterial& m = families_[static_cast<int>(lat.bar_address(bar).family)];
  return {m.e_p, m.e_r};
}

double BarTable::axial_stiffness(const Lattice& lat, index_t bar) const {
  const BarAddress a = lat.bar_address(bar);
  const FamilyMaterial& m = families_[static_cast<int>(a.family)];
  if (per_bar())
    return k_[bar] * m.l0;
  return m.k * m.l0 * lat.area_factor(a.family, a.i, a.j, a.k);
}

double BarTable::stiffness(const Lattice& lat, index_t bar) const {
  const BarAddress a = lat.bar_address(bar);
  const FamilyMaterial& m = families_[static_cast<int>(a.family)];
  if (per_bar())
    return k_[bar];
  return m.k * lat.area_factor(a.family, a.i, a.j, a.k);
}

} // namespace ldem
