#include "io/output.hpp"

#include "util/error.hpp"

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fmt/format.h>

namespace ldem {

OutputFile::OutputFile(std::string path) : path_(std::move(path)), part_(path_ + ".part") {
  f_ = std::fopen(part_.c_str(), "wb");
  if (!f_)
    throw InputError(fmt::format("{}: cannot write ({})", part_, std::strerror(errno)));
}

OutputFile::~OutputFile() {
  if (f_)
    commit();
}

void OutputFile::write(const std::string& text) {
  if (std::fwrite(text.data(), 1, text.size(), f_) != text.size())
    throw InputError(fmt::format("{}: write failed ({})", part_, std::strerror(errno)));
}

void OutputFile::flush() {
  std::fflush(f_);
}

void OutputFile::commit() {
  if (!f_)
    return;
  std::fclose(f_);
  f_ = nullptr;
  std::rename(part_.c_str(), path_.c_str());
}

void write_file(const std::string& path, const std::string& text) {
  OutputFile f(path);
  f.write(text);
  f.commit();
}

namespace {

std::string base64(const unsigned char* data, std::size_t n) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((n + 2) / 3 * 4);
  for (std::size_t i = 0; i < n; i += 3) {
    const std::uint32_t b = (std::uint32_t{data[i]} << 16) |
                            (i + 1 < n ? std::uint32_t{data[i + 1]} << 8 : 0u) |
                            (i + 2 < n ? std::uint32_t{data[i + 2]} : 0u);
    out += t[(b >> 18) & 63];
    out += t[(b >> 12) & 63];
    out += i + 1 < n ? t[(b >> 6) & 63] : '=';
    out += i + 2 < n ? t[b & 63] : '=';
  }
  return out;
}

// A VTK binary DataArray: a UInt64 byte count, then the data, base64 encoded as one block.
template <class T>
std::string data_array(const char* type, const char* name, int components,
                       const std::vector<T>& v) {
  std::vector<unsigned char> bytes(sizeof(std::uint64_t) + v.size() * sizeof(T));
  const std::uint64_t n = v.size() * sizeof(T);
  std::memcpy(bytes.data(), &n, sizeof n);
  if (!v.empty())
    std::memcpy(bytes.data() + sizeof n, v.data(), n);
  return fmt::format("<DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\" "
                     "format=\"binary\">\n{}\n</DataArray>\n",
                     type, name, components, base64(bytes.data(), bytes.size()));
}

} // namespace

std::string lattice_vtu(const Simulation& sim) {
  const Lattice& lat = sim.lattice();
  const index_t nn = lat.num_nodes(), nb = lat.num_bars();
  std::vector<double> points(3 * std::size_t{nn}), disp(3 * std::size_t{nn}),
      vel(3 * std::size_t{nn});
  for (index_t n = 0; n < nn; ++n) {
    const Vec3 x = lat.position(n), u = sim.displacement(n), v = sim.half_step_velocity(n);
    const double p[3] = {x.x, x.y, x.z}, d[3] = {u.x, u.y, u.z}, w[3] = {v.x, v.y, v.z};
    for (int c = 0; c < 3; ++c) {
      points[3 * std::size_t{n} + c] = p[c];
      disp[3 * std::size_t{n} + c] = d[c];
      vel[3 * std::size_t{n} + c] = w[c];
    }
  }
  std::vector<std::int64_t> conn(2 * std::size_t{nb}), offsets(nb);
  std::vector<std::uint8_t> types(nb, 3), state(nb); // 3 = VTK_LINE
  std::vector<double> damage(nb), force(nb);
  for (index_t b = 0; b < nb; ++b) {
    const auto [a, c] = lat.bar_nodes(b);
    conn[2 * std::size_t{b}] = a;
    conn[2 * std::size_t{b} + 1] = c;
    offsets[b] = 2 * (std::int64_t{b} + 1);
    const BilinearLaw law = sim.table().law(lat, b);
    const double h = sim.bar_history(b);
    state[b] = static_cast<std::uint8_t>(law.state(h));
    const double full = 0.5 * law.EA * law.e_p * law.e_r * law.l0; // Gf A^f
    damage[b] = std::isinf(h) ? 1.0 : law.dissipated_energy(h) / full;
    force[b] = sim.bar_force(b);
  }
  std::string s = "<?xml version=\"1.0\"?>\n"
                  "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
                  "header_type=\"UInt64\">\n<UnstructuredGrid>\n";
  s += fmt::format("<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", nn, nb);
  s += "<PointData Vectors=\"displacement\">\n";
  s += data_array("Float64", "displacement", 3, disp);
  s += data_array("Float64", "velocity", 3, vel);
  s += "</PointData>\n<CellData Scalars=\"damage\">\n";
  s += data_array("Float64", "damage", 1, damage);
  s += data_array("UInt8", "state", 1, state);
  s += data_array("Float64", "axial_force", 1, force);
  if (sim.table().per_bar()) {
    // The material fields per bar: E, Gf (its fracture energy per fracture area, eq. 11),
    // e_p and e_r.
    std::vector<double> E(nb), Gf(nb);
    for (index_t b = 0; b < nb; ++b) {
      const BarAddress ad = lat.bar_address(b);
      const FamilyMaterial& m = sim.table().family(static_cast<int>(ad.family));
      const double factor = lat.area_factor(ad.family, ad.i, ad.j, ad.k);
      const BilinearLaw law = sim.table().law(lat, b);
      E[b] = law.EA / (m.area * factor);
      Gf[b] = 0.5 * law.EA * law.e_p * law.e_r * law.l0 / (m.area_f * factor);
    }
    s += data_array("Float64", "E", 1, E);
    s += data_array("Float64", "Gf", 1, Gf);
    s += data_array("Float64", "e_p", 1, sim.table().e_p_bar());
    s += data_array("Float64", "e_r", 1, sim.table().e_r_bar());
  }
  s += "</CellData>\n<Points>\n";
  s += data_array("Float64", "Points", 3, points);
  s += "</Points>\n<Cells>\n";
  s += data_array("Int64", "connectivity", 1, conn);
  s += data_array("Int64", "offsets", 1, offsets);
  s += data_array("UInt8", "types", 1, types);
  s += "</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  return s;
}

std::string lattice_pvd(const std::vector<std::pair<double, std::string>>& snapshots) {
  std::string s = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" "
                  "byte_order=\"LittleEndian\">\n<Collection>\n";
  for (const auto& [t, file] : snapshots)
    s += fmt::format("<DataSet timestep=\"{:.9g}\" group=\"\" part=\"0\" file=\"{}\"/>\n", t, file);
  s += "</Collection>\n</VTKFile>\n";
  return s;
}

} // namespace ldem
