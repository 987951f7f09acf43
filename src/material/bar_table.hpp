// Per-bar material constants of a lattice, built from a material description.
//
// Constants that do not vary are stored once per family; only the properties that a
// field makes vary are stored per bar (empty vectors otherwise).
#pragma once

#include "lattice/lattice.hpp"
#include "material/bar_law_bilinear.hpp"

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace ldem {

// The fatigue constants of `law = "bilinear_fatigue"` (bar_law_fatigue.hpp), as a case gives
// them: A for bars of length `length`.
struct FatigueSpec {
  double A = 0.0;                 // life used per cycle at a strain range of 1 [1/cycle]
  double m = 1.0;                 // exponent of the strain range
  double threshold = 0.0;         // strain ranges at or below it use no life
  double gate = 0.0;              // hysteresis of the turning points of the strain
  double length = 0.0;            // the bar length A is given for [m]
  std::uint64_t count_every = 10; // steps between two samples of the strains for the count
  // Cycle jumping (docs/model.md, "Cycle jumping"): resolve `jump_window` load cycles, then
  // jump as many cycles as leave at most `jump_breaks` bars at the end of their life, at most
  // `jump_max`.
  // A jump also uses at most `jump_fraction` of any bar's remaining life.
  bool jump = false;
  std::uint64_t jump_window = 4;
  std::uint64_t jump_breaks = 0;
  double jump_max = 1e6;
  double jump_fraction = 0.2;
  // Only bars that meet this box [lo, hi] (a point of the bar inside it, faces included) have
  // a fatigue life; without it, every bar.
  std::optional<std::array<Vec3, 2>> box = std::nullopt;
};

struct MaterialSpec {
  double E = 0.0;            // Young's modulus [Pa]
  double nu = 0.25;          // Poisson's ratio (the lattice is isotropic only for 0.25)
  double rho = 0.0;          // density [kg/m^3]
  double Gf = 0.0;           // specific fracture energy [N/m]
  std::optional<double> e_p; // strain at peak force, or
  std::optional<double> R_f; // failure factor (eq. 7)
  // Strain at rupture of the normal bars; when absent e_r = K_r e_p with K_r of eq. 12.
  // When given, the diagonals' K_r follows from the same Gf so that both kinds keep
  // the eq. 12 relation (diagonal K_r = normal K_r x ratio of eqs. 14-15 x l_n / l_d).
  std::optional<double> e_r;
  bool single_ratio = false;          // use the paper's single A^f/A = 0.34 for both kinds (eq. 16)
  bool allow_low_kr = false;          // accept K_r < 1 (unstable softening; the user asked for it)
  std::optional<FatigueSpec> fatigue; // law = "bilinear_fatigue" only
};

// Optional per-bar values (one entry per bar, or empty for "uniform").
// How the quantities that depend on each other follow when some vary per bar:
// - e_p given (field or value) or else from R_f (value or field) by eq. 7 with the bar's Gf
//   and E;
// - e_r given (field or value, the normal bars'): kept, and the bar's Gf follows from eq. 11
//   (Gf = K_r E e_p^2 (A / A^f) l0 / 2, K_r = e_r / e_p), the diagonals' e_r scaled so both
//   kinds keep eq. 12 with that Gf (the paper's graded case);
// - e_r not given: K_r from eq. 12 with the bar's Gf, E and e_p, and e_r = K_r e_p.
struct BarFields {
  std::vector<double> E;   // Young's modulus
  std::vector<double> Gf;  // fracture energy
  std::vector<double> e_p; // peak strain
  std::vector<double> e_r; // rupture strain of a normal bar
  std::vector<double> R_f; // failure factor (eq. 7), used where e_p is not given
  std::vector<double> rho; // density per module (not per bar): the lumped masses follow
};

// The per-bar ranges that result, for the resolved case file.
struct MaterialRanges {
  double E[2], Gf[2], e_p[2], e_r_normal[2];
  double rho[2]; // of the modules
  std::string rule;
};

// The peak strain given to the bars of a shaped body's box that no present module has
// (Lattice::bar_present): no strain reaches it, so they stay pristine, with no stiffness.
inline constexpr double kAbsentBarStrain = 1e30;

struct FamilyMaterial {
  double k = 0.0;      // E A / l0 of a bar with area factor 1 [N/m]
  double l0 = 0.0;     // reference length
  double area = 0.0;   // A (area factor 1)
  double area_f = 0.0; // A^f (area factor 1)
  double e_p = 0.0, e_r = 0.0;
};

struct DuctilitySummary {
  double kr_min_normal = 0, kr_max_normal = 0, kr_min_diag = 0, kr_max_diag = 0;
  double L_cr_min = 0; // eq. 13, smallest over bars (normal-bar ratio)
  std::uint64_t bars_below_one = 0;
  index_t worst_bar = 0; // bar with the smallest K_r
  double worst_kr = 0;
};

// The verdict on bars with K_r < 1 in a body of `bars` bars whose summary is `s` (worst bar
// centred at `worst_centre`, modules of size L): throws InputError unless spec.allow_low_kr;
// allowed, the warning the user should read (none when every K_r >= 1).
std::optional<std::string> check_ductility(const DuctilitySummary& s, const MaterialSpec& spec,
                                           std::uint64_t bars, Vec3 worst_centre, double L);

// A table built for a window of a larger body (a distributed run's subdomain): its messages
// name the body's bars, its ranges and ductility summary cover only the bars the window counts
// (those its process owns, so that the processes' summaries combine into the body's), and
// K_r < 1 is left to the caller, who judges the combined summary with check_ductility.
struct BodyWindow {
  std::function<index_t(index_t)> body_bar; // the body's number of a window bar
  std::function<bool(index_t)> counted;     // window bar -> counted in the summary
};

class BarTable {
public:
  // Throws InputError for inconsistent or out-of-range values and, unless
  // spec.allow_low_kr or built for a window, for any bar with K_r < 1.
  BarTable(const Lattice& lattice, const MaterialSpec& spec, const BarFields& fields = {},
           const BodyWindow* window = nullptr);

  const MaterialSpec& spec() const { return spec_; }
  const FamilyMaterial& family(int f) const { return families_[f]; }
  bool per_bar() const { return !k_.empty(); }
  // Per-bar arrays (empty unless a field varies): stiffness EA/l0 including the
  // boundary area factor, e_p, e_r.
  const std::vector<double>& k_bar() const { return k_; }
  const std::vector<double>& e_p_bar() const { return e_p_; }
  const std::vector<double>& e_r_bar() const { return e_r_; }
  // The stiffness E A / l0 (area factor 1) shared by the bars of row (f, j, k) (i running):
  // the family's where nothing varies per bar; where something does, the row's when every bar
  // of it has the same E (a field along y or z, a Weibull Gf, e_p or e_r) in a box, so that
  // k_bar of its bars is this times their area factors, bit for bit; 0 where E varies along
  // the row or the body is shaped (the row's bars take their k_bar).
  double row_stiffness(int family, index_t j, index_t k) const;
  // Density per module, or empty (uniform spec().rho).
  const std::vector<double>& rho_module() const { return rho_; }

  // A bar's law (its e_p and e_r), its axial stiffness E A and its stiffness k = E A / l0, the
  // boundary's area factor included.
  BilinearLaw law(const Lattice& lattice, index_t bar) const;
  double axial_stiffness(const Lattice& lattice, index_t bar) const;
  double stiffness(const Lattice& lattice, index_t bar) const;
  // A bar's material as a user reads it: E, Gf (its dissipation capacity over its fracture
  // area, eq. 11), e_p and e_r.
  struct Properties {
    double E, Gf, e_p, e_r;
  };
  Properties properties(const Lattice& lattice, index_t bar) const;
  double area_ratio(BarKind kind) const; // A^f / A
  const DuctilitySummary& ductility_summary() const { return summary_; }
  const MaterialRanges& ranges() const { return ranges_; }
  // Things the user should know that do not stop the run (nu != 0.25, allowed K_r < 1).
  const std::vector<std::string>& warnings() const { return warnings_; }
  double node_mass_density() const { return spec_.rho; }

private:
  MaterialSpec spec_;
  std::array<FamilyMaterial, kFamilies> families_{};
  std::vector<double> k_, e_p_, e_r_, rho_;
  // Per bar row (per_bar() only): row_stiffness, rows of family f from row_first_[f] on.
  std::vector<double> row_k_;
  std::array<std::size_t, kFamilies> row_first_{};
  std::array<index_t, kFamilies> row_nj_{};
  DuctilitySummary summary_;
  MaterialRanges ranges_{};
  std::vector<std::string> warnings_;
};

} // namespace ldem
