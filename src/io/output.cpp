#include "io/output.hpp"

#include "util/error.hpp"

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>

namespace ldem {

OutputFile::OutputFile(std::string path) : path_(std::move(path)), part_(path_ + ".part") {
  f_ = std::fopen(part_.c_str(), "wb");
  if (!f_)
    throw InputError(fmt::format("{}: cannot write ({})", part_, std::strerror(errno)));
}

OutputFile::OutputFile(std::string path, std::uint64_t length)
    : path_(std::move(path)), part_(path_ + ".part") {
  std::error_code ec;
  if (!std::filesystem::exists(part_, ec))
    std::filesystem::rename(path_, part_, ec);
  if (ec || std::filesystem::file_size(part_, ec) < length || ec)
    throw InputError(fmt::format("{}: cannot continue it: missing or shorter than the {} bytes the "
                                 "checkpoint recorded",
                                 path_, length));
  std::filesystem::resize_file(part_, length);
  f_ = std::fopen(part_.c_str(), "ab");
  if (!f_)
    throw InputError(fmt::format("{}: cannot write ({})", part_, std::strerror(errno)));
  size_ = length;
}

OutputFile::~OutputFile() {
  if (f_)
    commit();
}

void OutputFile::write(const std::string& text) {
  size_ += text.size();
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

// VTK XML arrays stored raw in the file's AppendedData section: each array is a UInt64 byte
// count followed by its bytes; the XML header gives each array's offset into that section.
class AppendedArrays {
public:
  template <class T>
  std::string add(const char* type, const char* name, int components, const std::vector<T>& v) {
    const std::string tag =
        fmt::format("<DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\" "
                    "format=\"appended\" offset=\"{}\"/>\n",
                    type, name, components, data_.size());
    const std::uint64_t n = v.size() * sizeof(T);
    const auto* p = reinterpret_cast<const char*>(&n);
    data_.insert(data_.end(), p, p + sizeof n);
    const auto* q = reinterpret_cast<const char*>(v.data());
    data_.insert(data_.end(), q, q + n);
    return tag;
  }
  const std::vector<char>& data() const { return data_; }

private:
  std::vector<char> data_;
};

// Output precision: positions, displacements, velocities and bar values in single precision
// (7 digits, ample for pictures; the CSV files keep full precision).
std::vector<float> to_float(const std::vector<double>& v) {
  return {v.begin(), v.end()};
}

} // namespace

void write_lattice_vtu(const Simulation& sim, const std::string& path) {
  const Lattice& lat = sim.lattice();
  const index_t nn = lat.num_nodes(), nb = lat.num_bars();
  std::vector<float> points(3 * std::size_t{nn}), disp(3 * std::size_t{nn}),
      vel(3 * std::size_t{nn});
  for (index_t n = 0; n < nn; ++n) {
    const Vec3 x = lat.position(n), u = sim.displacement(n), v = sim.half_step_velocity(n);
    const double p[3] = {x.x, x.y, x.z}, d[3] = {u.x, u.y, u.z}, w[3] = {v.x, v.y, v.z};
    for (int c = 0; c < 3; ++c) {
      points[3 * std::size_t{n} + c] = static_cast<float>(p[c]);
      disp[3 * std::size_t{n} + c] = static_cast<float>(d[c]);
      vel[3 * std::size_t{n} + c] = static_cast<float>(w[c]);
    }
  }
  std::vector<std::int32_t> conn(2 * std::size_t{nb}), offsets(nb);
  std::vector<std::uint8_t> types(nb, 3), state; // 3 = VTK_LINE
  std::vector<double> damage, force;
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fi = lat.family(f);
    for (index_t k = 0; k < fi.nk; ++k)
      for (index_t j = 0; j < fi.nj; ++j)
        for (index_t i = 0; i < fi.ni; ++i) {
          const std::size_t b = lat.bar(static_cast<Family>(f), i, j, k);
          conn[2 * b] = static_cast<std::int32_t>(fi.a.at(i, j, k));
          conn[2 * b + 1] = static_cast<std::int32_t>(fi.b.at(i, j, k));
        }
  }
  for (index_t b = 0; b < nb; ++b)
    offsets[b] = static_cast<std::int32_t>(2 * (std::int64_t{b} + 1));
  sim.bar_snapshot(state, damage, force);

  AppendedArrays a;
  std::string s = "<?xml version=\"1.0\"?>\n"
                  "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
                  "header_type=\"UInt64\">\n<UnstructuredGrid>\n";
  s += fmt::format("<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", nn, nb);
  s += "<PointData Vectors=\"displacement\">\n";
  s += a.add("Float32", "displacement", 3, disp);
  s += a.add("Float32", "velocity", 3, vel);
  s += "</PointData>\n<CellData Scalars=\"damage\">\n";
  s += a.add("Float32", "damage", 1, to_float(damage));
  s += a.add("UInt8", "state", 1, state);
  s += a.add("Float32", "axial_force", 1, to_float(force));
  if (sim.table().per_bar()) {
    // The material fields per bar: E, Gf (its fracture energy per fracture area, eq. 11),
    // e_p and e_r.
    std::vector<float> E(nb), Gf(nb);
    for (index_t b = 0; b < nb; ++b) {
      const BarTable::Properties p = sim.table().properties(lat, b);
      E[b] = static_cast<float>(p.E);
      Gf[b] = static_cast<float>(p.Gf);
    }
    s += a.add("Float32", "E", 1, E);
    s += a.add("Float32", "Gf", 1, Gf);
    s += a.add("Float32", "e_p", 1, to_float(sim.table().e_p_bar()));
    s += a.add("Float32", "e_r", 1, to_float(sim.table().e_r_bar()));
  }
  s += "</CellData>\n<Points>\n";
  s += a.add("Float32", "Points", 3, points);
  s += "</Points>\n<Cells>\n";
  s += a.add("Int32", "connectivity", 1, conn);
  s += a.add("Int32", "offsets", 1, offsets);
  s += a.add("UInt8", "types", 1, types);
  s += "</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding=\"raw\">\n_";
  OutputFile out(path);
  out.write(s);
  out.write(std::string(a.data().begin(), a.data().end()));
  out.write("\n</AppendedData>\n</VTKFile>\n");
  out.commit();
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
