// Initial cracks: every bar whose segment crosses a planar rectangle starts broken.
#pragma once

#include "lattice/lattice.hpp"

#include <string>
#include <vector>

namespace ldem {

// The rectangle {origin + u*edge1 + w*edge2 : 0 <= u, w <= 1}.
struct Rectangle {
  std::string name;
  Vec3 origin, edge1, edge2;
};

struct CutResult {
  std::vector<index_t> bars; // sorted
  Vec3 origin;               // origin actually used (moved when nudged)
  bool nudged = false;
};

// Bars whose open segment crosses the rectangle. A bar that only ends on the plane
// does not cross it, so a rectangle through a plane of nodes would separate nothing:
// it is refused (InputError naming the rectangle and a node on it) unless `nudge`,
// in which case the rectangle is moved a quarter module along its normal.
// A rectangle that cuts no bar (outside the body) is refused too.
CutResult cut_bars(const Lattice& lattice, const Rectangle& rect, bool nudge);

// Connected components of the graph of nodes joined by the present bars not in `removed`
// (sorted). Returns one label per node, labels 0..count-1 in order of first node (a shaped
// body's absent nodes are components of their own).
std::vector<index_t> connected_components(const Lattice& lattice,
                                          const std::vector<index_t>& removed, index_t* count);

} // namespace ldem
