// Tests of shaped bodies' module masks (lattice/shape.hpp): the primitives, the order of the
// operations, the removal of pieces joined only at edges or corners, and .npy masks.
#include "lattice/shape.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <gtest/gtest.h>
#include <numbers>
#include <string>
#include <vector>

namespace ldem {
namespace {

constexpr double L = 0.01;

ShapeOp box(bool add, Vec3 lo, Vec3 hi) {
  ShapeOp op;
  op.add = add;
  op.shape.type = Shape::Type::Box;
  op.shape.lo = lo;
  op.shape.hi = hi;
  return op;
}

ShapeOp round(bool add, Shape::Type type, Vec3 a, Vec3 b, double radius) {
  ShapeOp op;
  op.add = add;
  op.shape.type = type;
  op.shape.a = a;
  op.shape.b = b;
  op.shape.radius = radius;
  return op;
}

// A box whose faces lie on module faces holds exactly the modules between them: removing
// 3 x 4 x 2 of the 10 x 4 x 6 modules leaves 240 - 24.
TEST(Shape, ABoxOnModuleFacesTakesTheModulesBetweenThem) {
  const ModuleMask m =
      build_module_mask(10, 4, 6, L, {box(false, {0.02, 0.0, 0.01}, {0.05, 0.04, 0.03})});
  EXPECT_EQ(m.count, 216u);
  EXPECT_EQ(m.hinged, 0u);
  EXPECT_EQ(m.pieces, 1u);
  EXPECT_FALSE(m.at(2, 0, 1));
  EXPECT_FALSE(m.at(4, 3, 2));
  EXPECT_TRUE(m.at(5, 0, 1));
  EXPECT_TRUE(m.at(2, 0, 3));
}

// A cylinder along y of radius r = 15 L about a module corner: the modules whose centres lie
// within r. Every such module's square lies in the disc of radius r + L / sqrt(2), and every
// square in the disc of radius r - L / sqrt(2) has its centre within r, so the count per
// layer lies between pi (r -+ L / sqrt(2))^2 / L^2: 642 and 775 (pi r^2 / L^2 = 707).
TEST(Shape, ACylinderTakesTheModulesOfItsDiscPerLayer) {
  const double r = 15 * L, h = L / std::numbers::sqrt2;
  const ModuleMask m = build_module_mask(
      40, 3, 40, L, {round(true, Shape::Type::Cylinder, {0.2, -0.01, 0.2}, {0.2, 0.04, 0.2}, r)});
  const double per_layer = static_cast<double>(m.count) / 3.0;
  EXPECT_EQ(m.count % 3, 0u); // the same disc in each layer
  EXPECT_GE(per_layer, std::numbers::pi * (r - h) * (r - h) / (L * L));
  EXPECT_LE(per_layer, std::numbers::pi * (r + h) * (r + h) / (L * L));
  EXPECT_TRUE(m.at(20, 1, 20));
  EXPECT_FALSE(m.at(0, 1, 0));
  // The cylinder's ends cut: from y = 0.01 m on it holds the centres of layers 1 and 2.
  const ModuleMask cut = build_module_mask(
      40, 3, 40, L, {round(true, Shape::Type::Cylinder, {0.2, 0.01, 0.2}, {0.2, 0.04, 0.2}, r)});
  EXPECT_EQ(cut.count, 2 * m.count / 3);
}

// A sphere of radius 2.5 L about a module centre holds the centres (integer offsets from it,
// in modules) with i^2 + j^2 + k^2 <= 6.25: 1 + 6 + 12 + 8 + 6 (|.|^2 = 4) + 24 (5) + 24 (6) =
// 81.
TEST(Shape, ASphereTakesTheCentresWithinItsRadius) {
  const ModuleMask m = build_module_mask(
      9, 9, 9, L, {round(true, Shape::Type::Sphere, {0.045, 0.045, 0.045}, {}, 2.5 * L)});
  EXPECT_EQ(m.count, 81u);
}

// A half-space keeps the side its normal points to: removing x >= 0.05 m leaves 5 of 8
// columns of modules.
TEST(Shape, AHalfSpaceTakesTheSideItsNormalPointsTo) {
  ShapeOp cut = round(false, Shape::Type::HalfSpace, {0.05, 0.0, 0.0}, {}, 0.0);
  cut.shape.normal = {1.0, 0.0, 0.0};
  const ModuleMask m = build_module_mask(8, 2, 3, L, {cut});
  EXPECT_EQ(m.count, 5u * 2 * 3);
  EXPECT_TRUE(m.at(4, 1, 2));
  EXPECT_FALSE(m.at(5, 0, 0));
}

// A box turned by 90 degrees about y through its centre is the box with its x and z extents
// swapped. Turned by 45 degrees, a square of side 8 L centred on a module corner is the
// diamond |x| + |z| <= 4 sqrt(2) L = 5.66 L about it; the module centres lie at offsets
// (a, b) L with a, b half-integers, and in a quadrant those with a + b <= 5.66, i.e.
// a + b = n for n = 1 .. 5, number 1 + 2 + 3 + 4 + 5 = 15: 60 in all.
TEST(Shape, ATurnedBoxTurnsAboutItsCentre) {
  ShapeOp tall = box(true, {0.03, 0.0, 0.0}, {0.04, 0.01, 0.07});
  tall.shape.axis = 1;
  tall.shape.angle = std::numbers::pi / 2;
  const ModuleMask turned = build_module_mask(8, 1, 8, L, {tall});
  const ModuleMask wide =
      build_module_mask(8, 1, 8, L, {box(true, {0.0, 0.0, 0.03}, {0.07, 0.01, 0.04})});
  EXPECT_EQ(turned.present, wide.present);
  EXPECT_EQ(turned.count, 7u);

  ShapeOp diamond = box(true, {0.06, 0.0, 0.06}, {0.14, 0.01, 0.14});
  diamond.shape.axis = 1;
  diamond.shape.angle = std::numbers::pi / 4;
  const ModuleMask d = build_module_mask(20, 1, 20, L, {diamond});
  EXPECT_EQ(d.count, 60u);
}

// The operations apply in order: a first "add" starts from an empty grid, a later one puts
// back what an earlier "remove" took.
TEST(Shape, OperationsApplyInOrder) {
  const ModuleMask m = build_module_mask(6, 1, 6, L,
                                         {box(false, {0.0, 0.0, 0.0}, {0.06, 0.01, 0.03}),
                                          box(true, {0.0, 0.0, 0.0}, {0.02, 0.01, 0.06})});
  // The upper half (18) plus the left two columns' lower half (6).
  EXPECT_EQ(m.count, 24u);
  const ModuleMask empty_start =
      build_module_mask(6, 1, 6, L, {box(true, {0.0, 0.0, 0.0}, {0.02, 0.01, 0.06})});
  EXPECT_EQ(empty_start.count, 12u);
  EXPECT_THROW(build_module_mask(6, 1, 6, L, {box(false, {0.0, 0.0, 0.0}, {1.0, 1.0, 1.0})}),
               InputError);
}

// Pieces joined only at an edge or a corner are removed, the larger piece kept; pieces that
// share no node are kept as separate pieces.
TEST(Shape, PiecesJoinedOnlyAtAnEdgeOrACornerAreRemoved) {
  // A 2 x 2 block and a module meeting it along an edge (along y): the module goes.
  const ModuleMask edge = build_module_mask(4, 1, 4, L,
                                            {box(true, {0.0, 0.0, 0.0}, {0.02, 0.01, 0.02}),
                                             box(true, {0.02, 0.0, 0.02}, {0.03, 0.01, 0.03})});
  EXPECT_EQ(edge.count, 4u);
  EXPECT_EQ(edge.hinged, 1u);
  EXPECT_EQ(edge.pieces, 1u);
  EXPECT_FALSE(edge.at(2, 0, 2));
  // Two modules meeting at a corner: of two equal pieces the first in module order stays.
  const ModuleMask corner = build_module_mask(2, 2, 2, L,
                                              {box(true, {0.0, 0.0, 0.0}, {0.01, 0.01, 0.01}),
                                               box(true, {0.01, 0.01, 0.01}, {0.02, 0.02, 0.02})});
  EXPECT_EQ(corner.count, 1u);
  EXPECT_EQ(corner.hinged, 1u);
  EXPECT_TRUE(corner.at(0, 0, 0));
  // An L joined through faces stays whole, re-entrant edge and all.
  const ModuleMask ell =
      build_module_mask(3, 1, 3, L, {box(false, {0.01, 0.0, 0.01}, {0.03, 0.01, 0.03})});
  EXPECT_EQ(ell.count, 5u);
  EXPECT_EQ(ell.hinged, 0u);
  // Two modules apart: two pieces, nothing removed.
  const ModuleMask apart =
      build_module_mask(5, 1, 1, L, {box(false, {0.01, 0.0, 0.0}, {0.04, 0.01, 0.01})});
  EXPECT_EQ(apart.count, 2u);
  EXPECT_EQ(apart.pieces, 2u);
  EXPECT_EQ(apart.hinged, 0u);
}

// Writes an .npy file (format 1.0) with the given type and shape text and raw values.
std::string write_npy(const std::string& name, const std::string& descr, bool fortran,
                      const std::string& shape, const std::vector<char>& data) {
  std::string header = "{'descr': '" + descr +
                       "', 'fortran_order': " + (fortran ? "True" : "False") +
                       ", 'shape': " + shape + ", }";
  while ((10 + header.size() + 1) % 64 != 0)
    header += ' ';
  header += '\n';
  const std::string path = ::testing::TempDir() + name;
  std::ofstream out(path, std::ios::binary);
  out.write("\x93NUMPY\x01\x00", 8);
  const char len[2] = {static_cast<char>(header.size() & 0xff),
                       static_cast<char>(header.size() >> 8)};
  out.write(len, 2);
  out << header;
  out.write(data.data(), static_cast<std::streamsize>(data.size()));
  return path;
}

template <class T> std::vector<char> raw(const std::vector<T>& v) {
  std::vector<char> out(v.size() * sizeof(T));
  std::memcpy(out.data(), v.data(), out.size());
  return out;
}

// numpy.save of an array a[i, j, k] of shape (3, 2, 4): in C order element [i, j, k] is at
// k + 4 (j + 2 i), in Fortran order at i + 3 (j + 2 k). Mark [2, 1, 3] and [1, 0, 2].
TEST(Shape, NpyMasksAreReadInEitherOrderAndType) {
  std::vector<double> c(24, 0.0);
  c[3 + 4 * (1 + 2 * 2)] = 1.0;
  c[2 + 4 * (0 + 2 * 1)] = 0.5;
  const auto from_c = read_npy_mask(write_npy("c.npy", "<f8", false, "(3, 2, 4)", raw(c)), 3, 2, 4);
  std::vector<std::int32_t> f(24, 0);
  f[2 + 3 * (1 + 2 * 3)] = 7;
  f[1 + 3 * (0 + 2 * 2)] = -1;
  const auto from_f = read_npy_mask(write_npy("f.npy", "<i4", true, "(3, 2, 4)", raw(f)), 3, 2, 4);
  std::vector<std::uint8_t> expected(24, 0);
  expected[2 + 3 * (1 + 2 * 3)] = 1;
  expected[1 + 3 * (0 + 2 * 2)] = 1;
  EXPECT_EQ(from_c, expected);
  EXPECT_EQ(from_f, expected);
  std::vector<char> b(24, 0);
  b[2 + 3 * (1 + 2 * 3)] = 1;
  b[1 + 3 * (0 + 2 * 2)] = 1;
  EXPECT_EQ(read_npy_mask(write_npy("b.npy", "|b1", true, "(3, 2, 4)", b), 3, 2, 4), expected);

  // As a shape: the mask's modules removed from the full grid.
  ShapeOp op;
  op.shape.type = Shape::Type::Mask;
  op.shape.mask = std::make_shared<const std::vector<std::uint8_t>>(from_c);
  const ModuleMask m = build_module_mask(3, 2, 4, L, {op});
  EXPECT_EQ(m.count, 22u);
  EXPECT_FALSE(m.at(2, 1, 3));
}

// Bad masks are refused with the file and what is wrong.
TEST(Shape, BadNpyMasksAreRefused) {
  auto message = [](const std::string& path) {
    try {
      read_npy_mask(path, 3, 2, 4);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::vector<char> zeros(24 * 8, 0);
  EXPECT_NE(message(write_npy("shape.npy", "<f8", false, "(4, 2, 3)", zeros))
                .find("expected an array of shape (3, 2, 4)"),
            std::string::npos);
  EXPECT_NE(message(write_npy("big.npy", ">f8", false, "(3, 2, 4)", zeros)).find("big-endian"),
            std::string::npos);
  EXPECT_NE(message(write_npy("str.npy", "<U1", false, "(3, 2, 4)", zeros))
                .find("booleans, integers or floats"),
            std::string::npos);
  EXPECT_NE(message(write_npy("short.npy", "<f8", false, "(3, 2, 4)", std::vector<char>(8, 0)))
                .find("expected 24 values of 8 bytes"),
            std::string::npos);
  const std::string text = ::testing::TempDir() + "text.npy";
  std::ofstream(text) << "0 1 0\n";
  EXPECT_NE(message(text).find("without its signature"), std::string::npos);
  EXPECT_NE(message(text).find(text), std::string::npos);
}

// STL surfaces: the box [lo, hi] as 12 triangles.
std::vector<Triangle> box_mesh(Vec3 lo, Vec3 hi) {
  const Vec3 c[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {lo.x, hi.y, lo.z},
                     {hi.x, hi.y, lo.z}, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z},
                     {lo.x, hi.y, hi.z}, {hi.x, hi.y, hi.z}};
  const int quads[6][4] = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
  std::vector<Triangle> out;
  for (const auto& q : quads) {
    out.push_back({c[q[0]], c[q[1]], c[q[2]]});
    out.push_back({c[q[0]], c[q[2]], c[q[3]]});
  }
  return out;
}

void write_binary_stl(const std::string& path, const std::vector<Triangle>& tris) {
  std::ofstream f(path, std::ios::binary);
  f << std::string(80, ' ');
  const auto n = static_cast<std::uint32_t>(tris.size());
  f.write(reinterpret_cast<const char*>(&n), 4);
  for (const Triangle& t : tris) {
    const float normal[3] = {0, 0, 0};
    f.write(reinterpret_cast<const char*>(normal), 12);
    for (const Vec3& v : t) {
      const float xyz[3] = {static_cast<float>(v.x), static_cast<float>(v.y),
                            static_cast<float>(v.z)};
      f.write(reinterpret_cast<const char*>(xyz), 12);
    }
    f.write("\0\0", 2);
  }
}

void write_ascii_stl(const std::string& path, const std::vector<Triangle>& tris) {
  std::ofstream f(path);
  f << "solid test\n";
  for (const Triangle& t : tris) {
    f << " facet normal 0 0 0\n  outer loop\n";
    for (const Vec3& v : t)
      f << "   vertex " << v.x << " " << v.y << " " << v.z << "\n";
    f << "  endloop\n endfacet\n";
  }
  f << "endsolid test\n";
}

// A cube in a binary STL takes the modules whose centres lie in it: 3 per axis here (centres
// 0.015, 0.025, 0.035 in [0.0149, 0.0351]). A tetrahedron in millimetres (scale 0.001) in an
// ASCII STL takes exactly the centres with x, y, z >= 0 and x + y + z <= 0.05 (counted directly).
TEST(Shape, StlSurfacesTakeTheModulesWhoseCentresLieInside) {
  const std::string dir = ::testing::TempDir();
  const std::string cube = dir + "/ldem_cube.stl", tet = dir + "/ldem_tet.stl";
  write_binary_stl(cube, box_mesh({0.0149, 0.0149, 0.0149}, {0.0351, 0.0351, 0.0351}));
  const std::vector<std::uint8_t> m = surface_mask(read_stl(cube), 6, 6, 6, L, cube);
  EXPECT_EQ(std::count(m.begin(), m.end(), 1), 27);
  EXPECT_EQ(m[1 + 6 * (1 + 6 * 1)], 1);
  EXPECT_EQ(m[0], 0);
  const std::vector<Triangle> t = {{Vec3{0, 0, 0}, Vec3{50, 0, 0}, Vec3{0, 50, 0}},
                                   {Vec3{0, 0, 0}, Vec3{50, 0, 0}, Vec3{0, 0, 50}},
                                   {Vec3{0, 0, 0}, Vec3{0, 50, 0}, Vec3{0, 0, 50}},
                                   {Vec3{50, 0, 0}, Vec3{0, 50, 0}, Vec3{0, 0, 50}}};
  write_ascii_stl(tet, t);
  const std::vector<std::uint8_t> mt = surface_mask(read_stl(tet, 0.001), 6, 6, 6, L, tet);
  int expected = 0;
  for (int k = 0; k < 6; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 6; ++i) {
        const double x = (i + 0.5) * L, y = (j + 0.5) * L, z = (k + 0.5) * L;
        const bool in = x + y + z <= 0.05;
        expected += in;
        EXPECT_EQ(mt[static_cast<std::size_t>(i + 6 * (j + 6 * k))], in ? 1 : 0)
            << i << " " << j << " " << k;
      }
  EXPECT_EQ(expected, 20); // (i + j + k + 1.5) L <= 0.05: i + j + k <= 3, C(6, 3) = 20 triples
  std::remove(cube.c_str());
  std::remove(tet.c_str());
}

// A surface with a hole that the rows' lines cross (a facet of a face across x missing) and
// files that are not STL are refused.
TEST(Shape, OpenSurfacesAndBadStlFilesAreRefused) {
  const std::string dir = ::testing::TempDir();
  const std::string open = dir + "/ldem_open.stl", bad = dir + "/ldem_bad.stl";
  std::vector<Triangle> tris = box_mesh({0.0149, 0.0149, 0.0149}, {0.0351, 0.0351, 0.0351});
  tris.erase(tris.begin() + 8); // a triangle of the face x = 0.0149
  write_binary_stl(open, tris);
  try {
    surface_mask(read_stl(open), 6, 6, 6, L, open);
    ADD_FAILURE() << "an open surface was taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected a closed surface"), std::string::npos)
        << e.what();
  }
  std::ofstream(bad) << "not an stl file";
  try {
    read_stl(bad);
    ADD_FAILURE() << "a text file was taken for an STL file";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected an STL file"), std::string::npos) << e.what();
  }
  std::remove(open.c_str());
  std::remove(bad.c_str());
}

} // namespace
} // namespace ldem
