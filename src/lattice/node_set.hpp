// Node sets chosen by geometry. A set is a sorted list of node numbers. Only present nodes are
// chosen (a shaped body's, Lattice::node_present).
#pragma once

#include "lattice/lattice.hpp"

#include <string>
#include <vector>

namespace ldem {

enum class Face { XMin, XMax, YMin, YMax, ZMin, ZMax };

// "x-", "x+", "y-", "y+", "z-", "z+"; throws InputError otherwise.
Face parse_face(const std::string& text);
std::string face_name(Face f);

struct NodeSet {
  std::string name;
  std::vector<index_t> nodes;
};

// Corner nodes lying on a face of the box.
std::vector<index_t> select_face(const Lattice& lattice, Face face);
// The area of the face each node of select_face(lattice, face) stands for, in the same
// order: a quarter of every module face around it (L^2 / 4 at the face's corners, L^2 / 2 on
// its border, L^2 inside); they add up to the face's area (in a shaped body, a quarter of each
// present module's face around it: they add up to the body's area on the face).
std::vector<double> face_tributary_areas(const Lattice& lattice, Face face);
// The area of the body's surface each node of `nodes` (sorted) stands for, in the same order:
// a quarter of every module face of the surface whose four corners are all in the set (a face
// between a present module and an absent one or the outside of the box; across a direction in
// which the body is one module thick, a slice of a longer body, the box's faces are not
// surface, as for select_surface). On a face of the box it gives face_tributary_areas; on the
// surface nodes of a shape, the staircase area of the body's surface there; centre nodes, and
// nodes with no such face, stand for none.
std::vector<double> surface_tributary_areas(const Lattice& lattice,
                                            const std::vector<index_t>& nodes);
// Centre nodes of the layer of modules that touches a face ("centre nodes of the
// modules on the top face"): loads applied there reach the body without the
// boundary-edge scaling of the face's own bars.
std::vector<index_t> select_face_module_centres(const Lattice& lattice, Face face);
// Every node (corner or centre) with lo <= X <= hi component-wise, with a
// tolerance of 1e-9 L so that nodes on the box's faces are caught.
std::vector<index_t> select_box(const Lattice& lattice, Vec3 lo, Vec3 hi);
std::vector<index_t> select_all(const Lattice& lattice);

// Names a selection; an empty selection is refused with a message that names the set.
NodeSet make_node_set(std::string name, std::vector<index_t> nodes, const std::string& how);

} // namespace ldem
