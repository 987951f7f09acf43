// Bodies that are not a full box: an ordered list of operations that add or remove the
// modules whose centres lie inside a shape, on the module grid of a Lattice.
#pragma once

#include "lattice/lattice.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace ldem {

// A solid. A module belongs to it when its centre does (boundaries included).
struct Shape {
  enum class Type : std::uint8_t { Box, Cylinder, Sphere, HalfSpace, Mask };
  Type type = Type::Box;
  // Box: the corners lo and hi, then turned by `angle` (radians, right-handed) about the axis
  // `axis` (0, 1, 2) through its centre; axis -1: not turned.
  Vec3 lo, hi;
  int axis = -1;
  double angle = 0.0;
  // Cylinder: the segment from a to b is its axis, `radius` its radius; sphere: centre a.
  Vec3 a, b;
  double radius = 0.0;
  // Half-space: the points x with (x - a) . normal >= 0, the side the normal points to.
  Vec3 normal;
  // Mask: one value per module of the grid, i fastest (i + nx (j + ny k)); nonzero is inside.
  std::shared_ptr<const std::vector<std::uint8_t>> mask;
  std::string file;   // the mask's file as the case gives it
  bool stl = false;   // the mask is of the closed surface in an STL file (file),
  double scale = 1.0; // its vertices times scale in metres

  // Whether p lies in the shape grown by `tol` (boundaries included). Not for masks.
  bool contains(Vec3 p, double tol = 0.0) const;
  // What the shape is, for messages ("sphere of radius 0.02 m about [0.1, 0, 0.1]").
  std::string describe() const;
};

// Every present node of the lattice inside the shape (to within 1e-9 L): a node set by shape.
std::vector<index_t> select_shape(const Lattice& lattice, const Shape& shape);
// The corner nodes of the body's surface inside the shape: those with an absent module, or the
// outside of the box, among the 8 modules around them; across a direction in which the body is
// one module thick (a plate in plane strain: a slice of a longer body) the box's faces are not
// surface. A loading strip on a disc, the curved face of a cylinder.
std::vector<index_t> select_surface(const Lattice& lattice, const Shape& shape);

struct ShapeOp {
  bool add = false; // add the shape's modules, or remove them
  Shape shape;
};

// The modules of a body, on the grid of nx x ny x nz modules of edge L.
struct ModuleMask {
  index_t nx = 0, ny = 0, nz = 0;
  std::vector<std::uint8_t> present; // 1 or 0 per module, i + nx (j + ny k)
  std::uint64_t count = 0;           // present modules
  // Modules removed because their piece of the body (the modules joined to it through faces)
  // met a larger piece only at edges or corners: joined so, they would turn about the shared
  // bars as about a hinge.
  std::uint64_t hinged = 0;
  // Pieces of the body kept: sets of modules joined through faces that share no node with
  // each other (more than 1: the body is in separate parts).
  std::uint64_t pieces = 0;
  bool at(index_t i, index_t j, index_t k) const {
    return present[i + std::size_t{nx} * (j + std::size_t{ny} * k)] != 0;
  }
};

// Applies `ops` in order to the full box of modules, or to an empty grid when the first
// operation adds (a module is inside a shape when its centre is, to within 1e-9 L), then
// removes the hinged pieces. Throws InputError when no module is left.
ModuleMask build_module_mask(index_t nx, index_t ny, index_t nz, double L,
                             const std::vector<ShapeOp>& ops);

// Reads a NumPy .npy array of shape (nx, ny, nz), indexed [i, j, k] (C or Fortran order), of
// booleans, integers or floats, into one byte per module (nonzero: 1), i fastest. Throws
// InputError naming the file and what is wrong (not an .npy file, its shape, its type).
std::vector<std::uint8_t> read_npy_mask(const std::string& path, index_t nx, index_t ny,
                                        index_t nz);

// The triangles of an STL file (binary or ASCII), each vertex times `scale` (0.001 for a file
// in millimetres). Throws InputError naming the file and what is wrong.
using Triangle = std::array<Vec3, 3>;
std::vector<Triangle> read_stl(const std::string& path, double scale = 1.0);

// The modules of the grid (nx x ny x nz, edge L) whose centres lie inside the closed surface
// the triangles make, one byte per module, i fastest: along each row of module centres (a line
// along x, moved off the centres by a few 1e-7 L so that it meets no edge or vertex of an
// axis-aligned mesh) the crossings with the surface, sorted; a centre is inside when an odd
// number of them lie before it. Throws InputError when a row crosses the surface an odd number
// of times (the surface is not closed where the row's line passes), naming `what`.
std::vector<std::uint8_t> surface_mask(const std::vector<Triangle>& triangles, index_t nx,
                                       index_t ny, index_t nz, double L, const std::string& what);

} // namespace ldem
