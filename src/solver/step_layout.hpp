// The step's layout (internal to the solver): where the nodes lie in the step's arrays, the
// rows of bars and nodes in the order the step visits them, each node row's links as the node
// kernel reads them, and the lines and planes the walk takes. All of it follows from the
// lattice and the material's constants and does not change during a run.
#pragma once

#include "lattice/lattice.hpp"
#include "material/bar_table.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace ldem {

// A link of a node row (see RowLink) as the step's node kernel reads it. What does not depend
// on where the row lies, only on its kind (corner or centre) and the faces it touches: the
// reference vector from the row's node to the other; the pristine spring of the link's bars
// (bar_law.hpp), s = k - kl0 / l with kl0 = k l0, and s times `scale` (their area factor over
// the row's) for the first and last bars of their bar row (nodes ilo and ihi - 1); the nodes
// [ilo, ihi) that have the link; which plane buffer holds the bars' forces when the bar pass
// computes them (dk = 0: the row's plane, -1: the one below); whether the row's nodes are the
// bars' first nodes; and 1 / l_p^2, l_p = l0 (1 + e_lim) the length at which the bars leave
// the law's elastic range (e_lim the bar row's elastic limit; 0 where there is none): the
// kernel gives the largest (l / l_p)^2 of the bars whose first nodes are the row's.
struct LinkConst {
  double rx, ry, rz, k, l0, kl0, scale, inv_lp2;
  std::int64_t ilo, ihi;
  int dk;
  bool first_node;
};

// The lanes of a vector of 8 nodes at a row's end, for one link: those whose nodes have the
// link, and those whose bar is the first or the last of its bar row with a factor of its own.
// In a shaped body (StepLayout::bar_code), `has` leaves out absent bars and q1, q2, q3 are the
// lanes whose bars have the area factor 1/4, 1/2 and 3/4 (first and last are then empty).
struct EdgeLanes {
  std::uint8_t has, first, last, q1, q2, q3;
};

// The rest, per row: node i's other node is slot other + i, the force over length of node i's
// bar (from the bar pass) at plane_base + i of a plane buffer, and the bars' row.
struct LinkRef {
  std::int64_t other;
  std::uint32_t bar_row;
  std::int32_t plane_base;
};

// A kind of node row: its length and links; the vectors of 8 nodes from i = lo on and ending
// by hi have every link on every lane and no end bar to scale; the others, in order, take
// their lanes from StepLayout::edge_lanes (kMaxRowLinks per such vector, from edge_begin on).
// The step takes the nodes [from, to) (whole vectors; [0, n) in a box, in a shaped body's row
// the vectors that hold its present nodes: the others have no force and do not move).
struct RowKind {
  std::int64_t n;
  int links;
  std::int64_t lo, hi;
  std::size_t edge_begin;
  std::int64_t from, to;
};

// A row of bars: family f, i running, at (j, k). In a shaped body (StepLayout::bar_code) the
// factors are 1 and the bars' own are in their codes; the kernels take the bars [p0, p1) (from
// the vector of 8 that holds the first present bar to the last present bar; [0, ni) in a box).
// `stiffness`: the k = E A / l0 of its inner bars (area factor included) when all its bars
// share their E (BarTable::row_stiffness), and 0 when E varies along the row: its bars then take
// their own k (BarTable::k_bar), in the bar pass's intact kernel while pristine, and never the
// fast path at the nodes (whose links carry one k per row kind). `elastic_limit`: the smallest
// of its bars' elastic limits (the intact kernel's threshold).
struct BarRow {
  int family;
  index_t j, k;
  double factor, end_factor;  // area factors of the row's bars (inner, first/last)
  std::size_t a_slot, b_slot; // slots of the first and second nodes of the row's bar i = 0
  index_t p0, p1;
  double stiffness, elastic_limit;
  bool own_stiffness() const { return stiffness == 0.0; } // k per bar
};

// Row ranges of each line (fixed j, k) and the lines of each k-plane.
struct Line {
  std::size_t bar_begin, bar_end, node_begin, node_end;
};
struct Plane {
  std::size_t line_begin, line_end;
};

struct StepLayout {
  // A node's place in the step loop's node arrays, which hold each row of nodes from a cache
  // line on (the lattice's rows, each padded to whole lines of 8 doubles; the padding stays
  // zero), so that a row's vectors load and store whole lines.
  RowNumbering slots;
  std::size_t slot_count = 0;
  // Rows in the order the step visits them: plane by plane (k), and in a plane line by line
  // (j): the bar rows (f, j, k) of every family, then the corner and centre node rows (j, k).
  std::vector<NodeRow> node_rows;
  std::vector<BarRow> bar_rows;
  std::vector<Line> lines;
  std::vector<Plane> planes;
  // The links of the node rows: LinkConst once per kind of row (kMaxRowLinks each), LinkRef per
  // row (kMaxRowLinks each), the kind of each row, and whether the portable kernel can take a
  // whole row in one pass.
  std::vector<LinkConst> link_const;
  std::vector<EdgeLanes> edge_lanes;
  std::vector<RowKind> row_kinds;
  std::vector<std::uint16_t> row_kind;
  std::vector<std::uint8_t> row_whole;
  std::vector<LinkRef> link_ref;
  // A shaped body of one material (a BarTable with constants per family): each bar's area
  // factor times 4 (0 for an absent bar, 1 to 4 for an edge bar, 0 or 4 for the others), and
  // per node row its own vectors with and without lane masks (RowKind's n, links, lo, hi and
  // edge_begin in edge_lanes; the kinds keep the links' constants). Empty for a box.
  std::vector<std::uint8_t> bar_code;
  std::vector<RowKind> row_span;
  bool coded() const { return !bar_code.empty(); }
  // Per bar row: the node rows of its first and second nodes, whether its first nodes are
  // centres (else corners), and 1 / l_p with l_p = l0 (1 + e_lim) the length at which its bars
  // leave the law's elastic range.
  std::vector<std::array<std::uint32_t, 2>> bar_row_nodes;
  std::vector<std::uint8_t> row_first_centre;
  std::vector<double> row_inv_lp;
  std::size_t line_store_stride = 0; // the most bars a line has

  // Per node row (node_rows' order), the slot of its node i = 0: slot = row_origin + i.
  std::vector<std::int64_t> row_origin;
  // A shaped body of one material (the AVX-512 kernels): each node row keeps in the node
  // arrays only its window [row_window[r][0], row_window[r][1]), whole vectors that hold every
  // node a kernel reads (its present nodes, and the nodes of the bars [p0, p1) of its bar
  // rows); its other nodes, absent and at rest, read a block of zeros from zero_slot on (with
  // mass 1 and every DOF held, as an absent node has), which nothing writes. Empty otherwise.
  std::vector<std::array<std::int64_t, 2>> row_window;
  std::size_t zero_slot = 0;
  bool compact() const { return !row_window.empty(); }
  // Per bar row, the index in the law's state arrays and in bar_code of its bar i = 0 (its
  // bar ids in a box): index = state_origin + i. A compact layout keeps there each bar row's
  // bars [p0, p1) only, and from rest_state on a row of bars in their initial state (and code
  // 0) per family (rest(f)), which its other bars (absent) read and nothing writes.
  // state_count: the arrays' length.
  std::vector<std::int64_t> state_origin;
  // A shaped body (coded()): per bar row, the index in bar_code of its bar i = 0 (index =
  // code_origin + i). A compact layout keeps each bar row's codes of [p0, p1) only, and rows
  // with the same bars [p0, p1) and codes share them.
  std::vector<std::int64_t> code_origin;
  std::size_t state_count = 0, rest_state = 0, rest_stride = 0;
  std::size_t rest(int family) const {
    return rest_state + rest_stride * static_cast<std::size_t>(family);
  }
  // The bar row of (family f, j, k), at (k (ny + 1) + j) kFamilies + f.
  std::vector<std::uint32_t> bar_row_at;
  std::size_t state_index(const Lattice& lat, index_t bar) const {
    if (!compact())
      return static_cast<std::size_t>(bar);
    const BarAddress a = lat.bar_address(bar);
    const BarRow& row = bar_rows[bar_row_at[(a.k * (lat.ny() + 1ull) + a.j) * kFamilies +
                                            static_cast<std::size_t>(a.family)]];
    return a.i >= row.p0 && a.i < row.p1
               ? static_cast<std::size_t>(state_origin[&row - bar_rows.data()] + a.i)
               : rest(row.family);
  }
  // visit(first index, first bar, count) for the runs of bars [first, first + count) that lie
  // in one bar row and, in a compact layout, in or outside its [p0, p1) (outside, the first
  // index is rest(family), to be read only).
  template <class F>
  void for_each_state_run(const Lattice& lat, index_t first, index_t count, F&& visit) const {
    if (!compact()) {
      visit(static_cast<std::size_t>(first), first, count);
      return;
    }
    const index_t end = first + count;
    for (index_t b = first; b < end;) {
      const BarAddress a = lat.bar_address(b);
      const std::size_t r = bar_row_at[(a.k * (lat.ny() + 1ull) + a.j) * kFamilies +
                                       static_cast<std::size_t>(a.family)];
      const std::int64_t i = a.i, n = std::min<std::int64_t>(end - b, lat.family(a.family).ni - i);
      const std::int64_t w0 = std::clamp<std::int64_t>(bar_rows[r].p0, i, i + n),
                         w1 = std::clamp<std::int64_t>(bar_rows[r].p1, w0, i + n);
      if (w0 > i)
        visit(rest(bar_rows[r].family), b, static_cast<index_t>(w0 - i));
      if (w1 > w0)
        visit(static_cast<std::size_t>(state_origin[r] + w0), static_cast<index_t>(b + (w0 - i)),
              static_cast<index_t>(w1 - w0));
      if (i + n > w1)
        visit(rest(bar_rows[r].family), static_cast<index_t>(b + (w1 - i)),
              static_cast<index_t>(i + n - w1));
      b = static_cast<index_t>(b + n);
    }
  }
  // Whether state index q holds a bar of its own (not the row at rest).
  bool state_stored(std::size_t q) const { return !compact() || q < rest_state; }

  // Whether slot q holds a node of its own (not the block of zeros).
  bool stored(std::size_t q) const { return !compact() || q < zero_slot; }

  std::size_t slot(const Lattice& lat, index_t node) const {
    if (compact()) {
      const std::size_t r = node_row_of(lat, node);
      const std::int64_t i = node - node_rows[r].first;
      return i >= row_window[r][0] && i < row_window[r][1]
                 ? static_cast<std::size_t>(row_origin[r] + i)
                 : zero_slot;
    }
    const index_t nc = lat.num_corners(), nx = lat.nx();
    if (node < nc)
      return static_cast<std::size_t>(slots.corner_row) * (node / (nx + 1)) + node % (nx + 1);
    const index_t m = node - nc;
    return static_cast<std::size_t>(slots.centre_first + slots.centre_row * (m / nx)) + m % nx;
  }
  // visit(first slot, first node, count) for the runs of nodes [first, first + count) that lie
  // in one row (and, in a compact layout, in or outside its window: outside, the first slot is
  // zero_slot, to be read only).
  template <class F>
  void for_each_run(const Lattice& lat, index_t first, index_t count, F&& visit) const {
    const index_t nc = lat.num_corners(), end = first + count;
    for (index_t n = first; n < end;) {
      const index_t row = n < nc ? lat.nx() + 1 : lat.nx();
      const index_t i = n < nc ? n % row : (n - nc) % row;
      const index_t run = std::min(end - n, row - i);
      if (!compact()) {
        visit(slot(lat, n), n, run);
      } else {
        // The run's parts before, inside and after the row's window.
        const std::size_t r = node_row_of(lat, n);
        const std::int64_t w0 = std::clamp<std::int64_t>(row_window[r][0], i, i + run),
                           w1 = std::clamp<std::int64_t>(row_window[r][1], w0, i + run);
        if (w0 > i)
          visit(zero_slot, n, static_cast<index_t>(w0 - i));
        if (w1 > w0)
          visit(static_cast<std::size_t>(row_origin[r] + w0), static_cast<index_t>(n + (w0 - i)),
                static_cast<index_t>(w1 - w0));
        if (i + run > w1)
          visit(zero_slot, static_cast<index_t>(n + (w1 - i)), static_cast<index_t>(i + run - w1));
      }
      n += run;
    }
  }
  // The node row of a node.
  std::size_t node_row_of(const Lattice& lat, index_t node) const;
};

// The layout of a lattice's step. `elastic_limit(f, first_bar, n)`: the strain up to which
// every pristine bar of the row of n bars of family f from first_bar on stays a linear spring
// (the law's, for the bars' constants; infinite for a law without one); `k` and the area
// factors come from the table.
StepLayout build_step_layout(const Lattice& lat, const BarTable& table,
                             const std::function<double(int, index_t, index_t)>& elastic_limit);

} // namespace ldem
