#include "io/output.hpp"

#include "io/checkpoint.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <omp.h>
#include <zlib.h>

namespace ldem {

OutputFile::OutputFile(std::string path, Kind kind)
    : path_(std::move(path)), part_(path_ + ".part"), kind_(kind), hash_(checkpoint::kFnvStart) {
  f_ = std::fopen(part_.c_str(), "wb");
  if (!f_)
    throw InputError(fmt::format("{}: cannot write ({})", part_, std::strerror(errno)));
}

OutputFile::OutputFile(std::string path, std::uint64_t length)
    : path_(std::move(path)), part_(path_ + ".part"), kind_(Kind::Log) {
  std::error_code ec;
  if (!std::filesystem::exists(part_, ec))
    std::filesystem::rename(path_, part_, ec);
  if (ec || std::filesystem::file_size(part_, ec) < length || ec)
    throw InputError(fmt::format("{}: cannot continue it: missing or shorter than the {} bytes the "
                                 "checkpoint recorded",
                                 path_, length));
  std::filesystem::resize_file(part_, length);
  hash_ = prefix_hash(part_, length).value_or(0);
  f_ = std::fopen(part_.c_str(), "ab");
  if (!f_)
    throw InputError(fmt::format("{}: cannot write ({})", part_, std::strerror(errno)));
  size_ = flushed_ = length;
}

std::string log_in_progress(const std::string& path) {
  std::error_code ec;
  return std::filesystem::exists(path + ".part", ec) ? path + ".part" : path;
}

std::optional<std::uint64_t> prefix_hash(const std::string& path, std::uint64_t length) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f)
    return std::nullopt;
  std::uint64_t h = checkpoint::kFnvStart;
  std::vector<char> buf(1 << 16);
  while (length > 0) {
    const std::size_t want = static_cast<std::size_t>(std::min<std::uint64_t>(length, buf.size()));
    if (std::fread(buf.data(), 1, want, f) != want) {
      std::fclose(f);
      return std::nullopt;
    }
    h = checkpoint::fnv1a(buf.data(), want, h);
    length -= want;
  }
  std::fclose(f);
  return h;
}

OutputFile::~OutputFile() {
  if (!f_)
    return;
  if (kind_ == Kind::Whole) { // dropped before it was complete
    std::fclose(f_);
    std::remove(part_.c_str());
    return;
  }
  try {
    commit();
  } catch (const InputError&) {
    // Cut back and kept under its temporary name by fail(); the error that ends the run is
    // already on its way.
  }
}

void OutputFile::fail(int err) {
  if (f_)
    std::fclose(f_); // (its own error is the same one)
  f_ = nullptr;
  std::error_code ec;
  if (kind_ == Kind::Whole) {
    std::filesystem::remove(part_, ec);
    throw InputError(fmt::format("{}: write failed ({}); not written (the disk full? free space "
                                 "and run again)",
                                 path_, std::strerror(err)));
  }
  // A log keeps the writes that reached the disk whole.
  const std::uint64_t on_disk = std::filesystem::file_size(part_, ec);
  std::uint64_t keep = flushed_;
  for (std::uint64_t end : ends_)
    if (!ec && end <= on_disk)
      keep = end;
  std::filesystem::resize_file(part_, keep, ec);
  size_ = keep;
  throw InputError(fmt::format("{}: write failed ({}); its first {} bytes, whole rows, are kept "
                               "in {} (the disk full? free space, then `ldem resume` the folder "
                               "if it has a checkpoint)",
                               path_, std::strerror(err), keep, part_));
}

void OutputFile::write(const std::string& text) {
  write(text.data(), text.size());
}

void OutputFile::write(const char* data, std::size_t bytes) {
  if (!f_)
    throw InputError(fmt::format("{}: written after it was closed", path_));
  if (std::fwrite(data, 1, bytes, f_) != bytes)
    fail(errno);
  size_ += bytes;
  if (kind_ == Kind::Log) {
    ends_.push_back(size_);
    hash_ = checkpoint::fnv1a(data, bytes, hash_);
  }
}

void OutputFile::flush() {
  if (!f_)
    return;
  if (std::fflush(f_) != 0)
    fail(errno);
  flushed_ = size_;
  ends_.clear();
}

void OutputFile::commit() {
  if (!f_)
    return;
  if (std::fflush(f_) != 0)
    fail(errno);
  std::FILE* f = f_;
  f_ = nullptr;
  if (std::fclose(f) != 0)
    fail(errno);
  if (std::rename(part_.c_str(), path_.c_str()) != 0)
    throw InputError(
        fmt::format("{}: cannot rename to {} ({})", part_, path_, std::strerror(errno)));
}

void write_file(const std::string& path, const std::string& text) {
  OutputFile f(path);
  f.write(text);
  f.commit();
}

namespace {

// Output precision: positions, displacements, velocities and bar values in single precision
// (7 digits, ample for pictures; the CSV files keep full precision).
std::vector<float> to_float(const std::vector<double>& v) {
  return {v.begin(), v.end()};
}

} // namespace

std::string module_mask_npy(const Lattice& lat) {
  std::string header =
      fmt::format("{{'descr': '|u1', 'fortran_order': True, 'shape': ({}, {}, {}), }}", lat.nx(),
                  lat.ny(), lat.nz());
  // Magic, version 1.0, the header's length, the header padded with spaces to a multiple of 64
  // bytes in all, ending in a newline (the .npy format, version 1.0).
  const std::size_t total = (10 + header.size() + 1 + 63) / 64 * 64;
  header.append(total - 10 - header.size() - 1, ' ');
  header += '\n';
  std::string out("\x93NUMPY\x01\x00", 8);
  out += static_cast<char>(header.size() & 0xff);
  out += static_cast<char>(header.size() >> 8);
  out += header;
  for (index_t k = 0; k < lat.nz(); ++k)
    for (index_t j = 0; j < lat.ny(); ++j)
      for (index_t i = 0; i < lat.nx(); ++i)
        out += static_cast<char>(lat.module_present(i, j, k) ? 1 : 0);
  return out;
}

PresentRanks::PresentRanks(const Lattice& lat) {
  if (!lat.shaped())
    return;
  node.resize(std::size_t{lat.num_nodes()} + 1);
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    node[n + 1] = node[n] + lat.node_present(n);
  bar.resize(std::size_t{lat.num_bars()} + 1);
  for (index_t b = 0; b < lat.num_bars(); ++b)
    bar[b + 1] = bar[b] + lat.bar_present(b);
}

std::vector<std::string> vtu_array_names(std::span<const StateArray> law_states) {
  std::vector<std::string> names = {"displacement", "velocity", "stress",      "node_strain",
                                    "damage",       "state",    "axial_force", "strain"};
  for (const StateArray& a : law_states)
    if (a.in_snapshots)
      names.emplace_back(a.name);
  for (const char* f : {"E", "Gf", "e_p", "e_r"})
    names.emplace_back(f);
  return names;
}

std::vector<std::string> zlib_compress_blocks(const void* data, std::uint64_t bytes) {
  const std::uint64_t n = (bytes + kZlibBlock - 1) / kZlibBlock;
  std::vector<std::string> blocks(n);
  const auto* in = static_cast<const Bytef*>(data);
  bool failed = false;
#pragma omp parallel for schedule(dynamic) reduction(|| : failed)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(n); ++k) {
    const auto first = static_cast<std::uint64_t>(k) * kZlibBlock;
    const uLong length = static_cast<uLong>(std::min(kZlibBlock, bytes - first));
    uLongf stored = compressBound(length);
    std::string& out = blocks[static_cast<std::size_t>(k)];
    out.resize(stored);
    failed = failed || compress2(reinterpret_cast<Bytef*>(out.data()), &stored, in + first, length,
                                 Z_BEST_SPEED) != Z_OK;
    out.resize(stored);
  }
  if (failed)
    throw std::runtime_error("zlib could not compress a snapshot's array");
  return blocks;
}

std::string zlib_header(std::uint64_t bytes, const std::vector<std::uint64_t>& sizes) {
  std::vector<std::uint64_t> head = {sizes.size(), kZlibBlock, bytes % kZlibBlock};
  head.insert(head.end(), sizes.begin(), sizes.end());
  return {reinterpret_cast<const char*>(head.data()), head.size() * sizeof(std::uint64_t)};
}

std::string zlib_blocks(const void* data, std::uint64_t bytes) {
  const std::vector<std::string> blocks = zlib_compress_blocks(data, bytes);
  std::vector<std::uint64_t> sizes;
  for (const std::string& b : blocks)
    sizes.push_back(b.size());
  std::string s = zlib_header(bytes, sizes);
  for (const std::string& b : blocks)
    s += b;
  return s;
}

VtuLayout vtu_layout(index_t nn, index_t nb, const Simulation& sim, bool ids,
                     const std::vector<std::string>& arrays, const VtuStoredSize& compressed) {
  const bool fields = sim.table().per_bar();
  const auto chosen = [&](std::string_view name) {
    return arrays.empty() || std::find(arrays.begin(), arrays.end(), name) != arrays.end();
  };
  VtuLayout l;
  std::string s = fmt::format(
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
      "header_type=\"UInt64\"{}>\n<UnstructuredGrid>\n",
      compressed ? " compressor=\"vtkZLibDataCompressor\"" : "");
  s += fmt::format("<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", nn, nb);
  std::uint64_t offset = 0; // in the appended data
  auto tag = [&](VtuLayout::Array a, const char* type, const char* name, int components,
                 std::uint64_t bytes) {
    const bool always = a >= VtuLayout::Points;
    if (!always && !chosen(name))
      return;
    s += fmt::format("<DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\" "
                     "format=\"appended\" offset=\"{}\"/>\n",
                     type, name, components, offset);
    l.present[a] = true;
    l.at[a] = offset; // made a file position below, once the header's length is known
    l.bytes[a] = bytes;
    offset += compressed ? compressed(a, bytes) : sizeof(std::uint64_t) + bytes;
  };
  const std::uint64_t fn = 4ull * nn, fb = 4ull * nb;
  s += "<PointData Vectors=\"displacement\">\n";
  tag(VtuLayout::Displacement, "Float32", "displacement", 3, 3 * fn);
  tag(VtuLayout::Velocity, "Float32", "velocity", 3, 3 * fn);
  // (The stress and strain only when named: computed from every bar or node at each snapshot.)
  if (std::find(arrays.begin(), arrays.end(), "stress") != arrays.end())
    tag(VtuLayout::Stress, "Float32", "stress", 6, 6 * fn);
  if (std::find(arrays.begin(), arrays.end(), "node_strain") != arrays.end())
    tag(VtuLayout::NodeStrain, "Float32", "node_strain", 6, 6 * fn);
  if (ids)
    tag(VtuLayout::NodeId, "Int32", "node", 1, fn);
  s += "</PointData>\n<CellData Scalars=\"damage\">\n";
  tag(VtuLayout::Damage, "Float32", "damage", 1, fb);
  tag(VtuLayout::State, "UInt8", "state", 1, nb);
  tag(VtuLayout::Force, "Float32", "axial_force", 1, fb);
  tag(VtuLayout::Strain, "Float32", "strain", 1, fb);
  if (ids)
    tag(VtuLayout::BarId, "Int32", "bar", 1, fb);
  const std::span<const StateArray> states = sim.bar_state_arrays();
  for (std::size_t a = 0; a < states.size(); ++a)
    if (states[a].in_snapshots && chosen(states[a].name)) {
      s += fmt::format("<DataArray type=\"Float32\" Name=\"{}\" NumberOfComponents=\"1\" "
                       "format=\"appended\" offset=\"{}\"/>\n",
                       states[a].name, offset);
      l.states.push_back(a);
      l.state_at.push_back(offset);
      offset += compressed
                    ? compressed(VtuLayout::kArrays + static_cast<int>(l.states.size()) - 1, fb)
                    : sizeof(std::uint64_t) + fb;
    }
  if (fields) {
    tag(VtuLayout::E, "Float32", "E", 1, fb);
    tag(VtuLayout::Gf, "Float32", "Gf", 1, fb);
    tag(VtuLayout::EP, "Float32", "e_p", 1, fb);
    tag(VtuLayout::ER, "Float32", "e_r", 1, fb);
  }
  s += "</CellData>\n<Points>\n";
  tag(VtuLayout::Points, "Float32", "Points", 3, 3 * fn);
  s += "</Points>\n<Cells>\n";
  tag(VtuLayout::Connectivity, "Int32", "connectivity", 1, 2 * fb);
  tag(VtuLayout::Offsets, "Int32", "offsets", 1, fb);
  tag(VtuLayout::Types, "UInt8", "types", 1, nb);
  s += "</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding=\"raw\">\n_";
  for (int a = 0; a < VtuLayout::kArrays; ++a)
    if (l.present[a])
      l.at[a] += s.size();
  for (std::uint64_t& at : l.state_at)
    at += s.size();
  l.size = s.size() + offset + std::char_traits<char>::length(VtuLayout::trailer);
  l.header = std::move(s);
  return l;
}

namespace {

// Keeps the items of `v` (`width` values each) that `ranks` marks present, in order, at the
// front of v, and drops the rest. Nothing for a box (empty ranks).
template <class T>
void keep_present(std::vector<T>& v, const std::vector<index_t>& ranks, std::size_t width) {
  if (ranks.empty())
    return;
  const std::size_t n = ranks.size() - 1;
  for (std::size_t x = 0; x < n; ++x)
    if (ranks[x + 1] > ranks[x])
      std::copy_n(v.begin() + static_cast<std::ptrdiff_t>(width * x), width,
                  v.begin() + static_cast<std::ptrdiff_t>(width * ranks[x]));
  v.resize(width * ranks[n]);
}

} // namespace

namespace {

// Calls visit(i, j, k, m) for every present module of `box` (m: its number), shared by the
// threads by rows along x.
template <class Visit> void for_each_module(const Lattice& lat, ModuleBox box, Visit&& visit) {
  const index_t nx = lat.nx();
  const index_t j0 = box.j0, j1 = std::min(box.j1, lat.ny());
  const index_t k0 = box.k0, k1 = std::min(box.k1, lat.nz());
  if (j1 <= j0 || k1 <= k0)
    return;
  const auto rows = static_cast<std::int64_t>(j1 - j0) * (k1 - k0);
#pragma omp parallel for schedule(static)
  for (std::int64_t r = 0; r < rows; ++r) {
    const auto j = static_cast<index_t>(j0 + r % (j1 - j0)),
               k = static_cast<index_t>(k0 + r / (j1 - j0));
    for (index_t i = 0; i < nx; ++i)
      if (lat.module_present(i, j, k))
        visit(i, j, k, i + std::size_t{nx} * (j + std::size_t{lat.ny()} * k));
  }
}

} // namespace

void module_stresses(const Lattice& lat, const std::vector<Vec3>& u,
                     const std::vector<double>& force, std::vector<double>& module,
                     ModuleBox box) {
  const index_t nx = lat.nx(), ny = lat.ny(), nz = lat.nz();
  const double L = lat.L(), inv_volume = 1.0 / (L * L * L);
  const auto add_bar = [&](index_t b, double w, double* s) {
    const double F = force[b];
    if (F == 0.0)
      return;
    const auto [a, c] = lat.bar_nodes(b);
    // The bar's reference vector from the nodes' indices (the same numbers in any window of
    // the body), plus the displacements' difference.
    const NodeAddress na = lat.node_address(a), nc = lat.node_address(c);
    const double shift = (nc.centre ? 0.5 : 0.0) - (na.centre ? 0.5 : 0.0);
    const double d[3] = {
        (static_cast<double>(nc.i) - static_cast<double>(na.i) + shift) * L + (u[c].x - u[a].x),
        (static_cast<double>(nc.j) - static_cast<double>(na.j) + shift) * L + (u[c].y - u[a].y),
        (static_cast<double>(nc.k) - static_cast<double>(na.k) + shift) * L + (u[c].z - u[a].z)};
    // F l n n^T = (F / l) d d^T
    const double k = w * F / std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    s[0] += k * d[0] * d[0];
    s[1] += k * d[1] * d[1];
    s[2] += k * d[2] * d[2];
    s[3] += k * d[0] * d[1];
    s[4] += k * d[1] * d[2];
    s[5] += k * d[0] * d[2];
  };
  for_each_module(lat, box, [&](index_t i, index_t j, index_t k, std::size_t m) {
    double* s = &module[6 * m];
    std::fill_n(s, 6, 0.0);
    // The 12 edges, each shared by the present modules that have it (4 area_factor of them).
    for (index_t p = 0; p < 2; ++p)
      for (index_t q = 0; q < 2; ++q)
        for (const index_t b : {lat.bar(Family::EdgeX, i, j + p, k + q),
                                lat.bar(Family::EdgeY, i + p, j, k + q),
                                lat.bar(Family::EdgeZ, i + p, j + q, k)})
          add_bar(b, 0.25 / lat.area_factor(b), s);
    // The centre-centre bars to the present neighbours, half each; the 8 diagonals, whole.
    const index_t at[3] = {i, j, k}, n[3] = {nx, ny, nz};
    for (int axis = 0; axis < 3; ++axis) {
      const auto f = static_cast<Family>(static_cast<int>(Family::CentreX) + axis);
      for (const int side : {-1, 0}) {
        if ((side < 0 && at[axis] == 0) || (side == 0 && at[axis] + 1 >= n[axis]))
          continue;
        index_t c[3] = {i, j, k};
        c[axis] = at[axis] + static_cast<index_t>(side); // (index_t wraps -1 and adds it back)
        const index_t b = lat.bar(f, c[0], c[1], c[2]);
        if (lat.bar_present(b))
          add_bar(b, 0.5, s);
      }
    }
    for (int f = static_cast<int>(Family::Diag0); f <= static_cast<int>(Family::Diag7); ++f)
      add_bar(lat.bar(static_cast<Family>(f), i, j, k), 1.0, s);
    for (int e = 0; e < 6; ++e)
      s[e] *= inv_volume;
  });
}

void module_strains(const Lattice& lat, const std::vector<Vec3>& u, std::vector<double>& module,
                    ModuleBox box) {
  const double quarter_over_L = 0.25 / lat.L();
  for_each_module(lat, box, [&](index_t i, index_t j, index_t k, std::size_t m) {
    // G[p][q]: the mean over the 4 edges along q of u_p's difference from end to end, over L.
    double G[3][3] = {};
    for (index_t a = 0; a < 2; ++a)
      for (index_t b = 0; b < 2; ++b) {
        const index_t ends[3][2] = {
            {lat.corner(i, j + a, k + b), lat.corner(i + 1, j + a, k + b)},
            {lat.corner(i + a, j, k + b), lat.corner(i + a, j + 1, k + b)},
            {lat.corner(i + a, j + b, k), lat.corner(i + a, j + b, k + 1)}};
        for (int q = 0; q < 3; ++q)
          for (int p = 0; p < 3; ++p)
            G[p][q] += u[ends[q][1]][p] - u[ends[q][0]][p];
      }
    double* s = &module[6 * m];
    s[0] = quarter_over_L * G[0][0];
    s[1] = quarter_over_L * G[1][1];
    s[2] = quarter_over_L * G[2][2];
    s[3] = 0.5 * quarter_over_L * (G[0][1] + G[1][0]);
    s[4] = 0.5 * quarter_over_L * (G[1][2] + G[2][1]);
    s[5] = 0.5 * quarter_over_L * (G[0][2] + G[2][0]);
  });
}

void node_means(const Lattice& lat, const std::vector<double>& module, std::vector<double>& out) {
  const index_t nx = lat.nx(), ny = lat.ny(), nz = lat.nz();
  out.assign(6 * std::size_t{lat.num_nodes()}, 0.0);
  const auto corners = static_cast<std::int64_t>(lat.num_corners());
#pragma omp parallel for schedule(static)
  for (std::int64_t q = 0; q < corners; ++q) {
    const auto i = static_cast<index_t>(q % (nx + 1)),
               j = static_cast<index_t>((q / (nx + 1)) % (ny + 1)),
               k = static_cast<index_t>(q / (std::int64_t{nx + 1} * (ny + 1)));
    double sum[6] = {0, 0, 0, 0, 0, 0};
    int count = 0;
    for (index_t c = 0; c < 2; ++c)
      for (index_t b = 0; b < 2; ++b)
        for (index_t a = 0; a < 2; ++a) {
          if (i + a == 0 || j + b == 0 || k + c == 0 || i + a > nx || j + b > ny || k + c > nz)
            continue;
          const index_t mi = i + a - 1, mj = j + b - 1, mk = k + c - 1;
          if (!lat.module_present(mi, mj, mk))
            continue;
          const double* s = &module[6 * (mi + std::size_t{nx} * (mj + std::size_t{ny} * mk))];
          for (int e = 0; e < 6; ++e)
            sum[e] += s[e];
          ++count;
        }
    for (int e = 0; count > 0 && e < 6; ++e)
      out[6 * static_cast<std::size_t>(q) + e] = sum[e] / count;
  }
  // A centre node: its module's (0 for an absent module).
  const auto modules = static_cast<std::int64_t>(lat.num_modules());
#pragma omp parallel for schedule(static)
  for (std::int64_t m = 0; m < modules; ++m) {
    const auto i = static_cast<index_t>(m % nx), j = static_cast<index_t>((m / nx) % ny),
               k = static_cast<index_t>(m / (std::int64_t{nx} * ny));
    if (lat.module_present(i, j, k))
      std::copy_n(&module[6 * static_cast<std::size_t>(m)], 6,
                  &out[6 * std::size_t{lat.centre(i, j, k)}]);
  }
}

void node_stresses(const Lattice& lat, const std::vector<Vec3>& u, const std::vector<double>& force,
                   std::vector<double>& out) {
  std::vector<double> module(6 * std::size_t{lat.num_modules()}, 0.0);
  module_stresses(lat, u, force, module);
  node_means(lat, module, out);
}

void node_strains(const Lattice& lat, const std::vector<Vec3>& u, std::vector<double>& out) {
  std::vector<double> module(6 * std::size_t{lat.num_modules()}, 0.0);
  module_strains(lat, u, module);
  node_means(lat, module, out);
}

LatticeVtuWriter::LatticeVtuWriter(const Simulation& sim, const std::vector<std::string>& arrays,
                                   bool zlib)
    : ranks_(sim.lattice()), zlib_(zlib), arrays_(arrays) {
  const Lattice& lat = sim.lattice();
  const index_t nn = lat.num_nodes(), nb = lat.num_bars();
  nn_ = nn;
  nb_ = nb;
  if (ranks_.shaped()) {
    for (index_t n = 0; n < nn; ++n)
      if (ranks_.node[n + 1] > ranks_.node[n])
        node_id_.push_back(static_cast<std::int32_t>(n));
    for (index_t b = 0; b < nb; ++b)
      if (ranks_.bar[b + 1] > ranks_.bar[b])
        bar_id_.push_back(static_cast<std::int32_t>(b));
  }
  // What the file holds: the present nodes and bars (a shaped body's), or all.
  const auto wn = static_cast<index_t>(ranks_.shaped() ? node_id_.size() : nn);
  const auto wb = static_cast<index_t>(ranks_.shaped() ? bar_id_.size() : nb);
  // What does not change during a run: reference positions, connectivity, cell types and the
  // material fields, appended after the per-snapshot arrays in one block.
  std::vector<float> points(3 * std::size_t{nn});
  for (index_t n = 0; n < nn; ++n) {
    const Vec3 x = lat.position(n);
    points[3 * std::size_t{n}] = static_cast<float>(x.x);
    points[3 * std::size_t{n} + 1] = static_cast<float>(x.y);
    points[3 * std::size_t{n} + 2] = static_cast<float>(x.z);
  }
  std::vector<std::int32_t> conn(2 * std::size_t{nb}), offsets(nb);
  std::vector<std::uint8_t> types(nb, 3); // 3 = VTK_LINE
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fi = lat.family(f);
    for (index_t k = 0; k < fi.nk; ++k)
      for (index_t j = 0; j < fi.nj; ++j)
        for (index_t i = 0; i < fi.ni; ++i) {
          const std::size_t b = lat.bar(static_cast<Family>(f), i, j, k);
          const index_t a = fi.a.at(i, j, k), c = fi.b.at(i, j, k);
          conn[2 * b] = static_cast<std::int32_t>(ranks_.shaped() ? ranks_.node[a] : a);
          conn[2 * b + 1] = static_cast<std::int32_t>(ranks_.shaped() ? ranks_.node[c] : c);
        }
  }
  for (index_t b = 0; b < nb; ++b)
    offsets[b] = static_cast<std::int32_t>(2 * (std::int64_t{b} + 1));
  keep_present(points, ranks_.node, 3);
  keep_present(conn, ranks_.bar, 2);
  offsets.resize(wb);
  types.resize(wb);

  // The per-snapshot arrays come first in the appended data; their sizes are fixed, so every
  // offset, and the whole XML header, is known now.
  auto add_static = [&](VtuLayout::Array a, const void* data, std::uint64_t bytes) {
    if (zlib_) {
      const std::string blob = zlib_blocks(data, bytes);
      static_stored_[a] = blob.size();
      static_block_.insert(static_block_.end(), blob.begin(), blob.end());
      return;
    }
    const auto* p = reinterpret_cast<const char*>(&bytes);
    static_block_.insert(static_block_.end(), p, p + sizeof bytes);
    const auto* q = static_cast<const char*>(data);
    static_block_.insert(static_block_.end(), q, q + bytes);
  };
  const std::uint64_t fb = 4ull * wb;
  const VtuLayout layout = vtu_layout(wn, wb, sim, ranks_.shaped(), arrays);
  law_states_ = layout.states;
  std::copy(std::begin(layout.present), std::end(layout.present), std::begin(present_));
  if (sim.table().per_bar()) {
    // The material fields per bar: E, Gf (its fracture energy per fracture area, eq. 11),
    // e_p and e_r.
    std::vector<float> E(nb), Gf(nb);
    for (index_t b = 0; b < nb; ++b) {
      const BarTable::Properties p = sim.table().properties(lat, b);
      E[b] = static_cast<float>(p.E);
      Gf[b] = static_cast<float>(p.Gf);
    }
    std::vector<float> e_p = to_float(sim.table().e_p_bar()), e_r = to_float(sim.table().e_r_bar());
    for (std::vector<float>* v : {&E, &Gf, &e_p, &e_r})
      keep_present(*v, ranks_.bar, 1);
    const std::pair<VtuLayout::Array, const std::vector<float>*> field[] = {
        {VtuLayout::E, &E}, {VtuLayout::Gf, &Gf}, {VtuLayout::EP, &e_p}, {VtuLayout::ER, &e_r}};
    for (const auto& [a, v] : field)
      if (layout.present[a])
        add_static(a, v->data(), fb);
  }
  add_static(VtuLayout::Points, points.data(), 3 * 4ull * wn);
  add_static(VtuLayout::Connectivity, conn.data(), 2 * fb);
  add_static(VtuLayout::Offsets, offsets.data(), fb);
  add_static(VtuLayout::Types, types.data(), wb);
  header_ = layout.header;
  // Every buffer a snapshot fills, sized (and its pages touched) now, not at the first snapshot.
  disp_.resize(3 * std::size_t{nn});
  vel_.resize(3 * std::size_t{nn});
  damage_f_.resize(nb);
  force_f_.resize(nb);
  strain_f_.resize(nb);
  state_.resize(nb);
  damage_.resize(nb);
  force_.resize(nb);
  strain_.resize(nb);
  if (present_[VtuLayout::Stress] || present_[VtuLayout::NodeStrain])
    u_all_.resize(nn);
  if (present_[VtuLayout::Stress])
    stress_f_.resize(6 * std::size_t{nn});
  if (present_[VtuLayout::NodeStrain])
    node_strain_f_.resize(6 * std::size_t{nn});
}

void LatticeVtuWriter::write(const Simulation& sim, const std::string& path) {
  constexpr index_t chunk = 4096; // nodes per task
  const auto chunks = static_cast<std::ptrdiff_t>((nn_ + chunk - 1) / chunk);
#pragma omp parallel
  {
    std::vector<Vec3> u(chunk), v(chunk);
#pragma omp for schedule(static)
    for (std::ptrdiff_t c = 0; c < chunks; ++c) {
      const auto first = static_cast<index_t>(c) * chunk;
      const index_t count = std::min(chunk, nn_ - first);
      sim.node_states(first, count, u.data(), v.data());
      for (index_t q = 0; q < count; ++q) {
        const std::size_t o = 3 * (std::size_t{first} + q);
        disp_[o] = static_cast<float>(u[q].x);
        disp_[o + 1] = static_cast<float>(u[q].y);
        disp_[o + 2] = static_cast<float>(u[q].z);
        vel_[o] = static_cast<float>(v[q].x);
        vel_[o + 1] = static_cast<float>(v[q].y);
        vel_[o + 2] = static_cast<float>(v[q].z);
        if (!u_all_.empty())
          u_all_[first + q] = u[q];
      }
    }
  }
  sim.bar_snapshot(state_, damage_, force_, &strain_);
  // (The modules' buffer kept from snapshot to snapshot: only present modules are written and
  // read.)
  const Lattice& lat = sim.lattice();
  if (present_[VtuLayout::Stress]) {
    module_.resize(6 * std::size_t{lat.num_modules()});
    module_stresses(lat, u_all_, force_, module_);
    node_means(lat, module_, tensor_);
    stress_f_.assign(tensor_.begin(), tensor_.end());
  }
  if (present_[VtuLayout::NodeStrain]) {
    module_.resize(6 * std::size_t{lat.num_modules()});
    module_strains(lat, u_all_, module_);
    node_means(lat, module_, tensor_);
    node_strain_f_.assign(tensor_.begin(), tensor_.end());
  }
  const auto nb = static_cast<std::ptrdiff_t>(nb_);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t b = 0; b < nb; ++b) {
    damage_f_[static_cast<std::size_t>(b)] =
        static_cast<float>(damage_[static_cast<std::size_t>(b)]);
    force_f_[static_cast<std::size_t>(b)] = static_cast<float>(force_[static_cast<std::size_t>(b)]);
    strain_f_[static_cast<std::size_t>(b)] =
        static_cast<float>(strain_[static_cast<std::size_t>(b)]);
  }
  // A shaped body's file holds its present nodes and bars only (the buffers keep the body's
  // size, so the next snapshot fills them whole again).
  const bool shaped = ranks_.shaped();
  const index_t wn = shaped ? ranks_.node.back() : nn_, wb = shaped ? ranks_.bar.back() : nb_;
  if (shaped) {
    for (std::vector<float>* v : {&disp_, &vel_}) {
      keep_present(*v, ranks_.node, 3);
      v->resize(3 * std::size_t{nn_});
    }
    if (present_[VtuLayout::Stress])
      keep_present(stress_f_, ranks_.node, 6);
    if (present_[VtuLayout::NodeStrain])
      keep_present(node_strain_f_, ranks_.node, 6);
    for (std::vector<float>* v : {&damage_f_, &force_f_, &strain_f_}) {
      keep_present(*v, ranks_.bar, 1);
      v->resize(nb_);
    }
    keep_present(state_, ranks_.bar, 1);
    state_.resize(nb_);
  }
  // Compressed: every array first (their sizes place the next ones), then the header.
  std::optional<OutputFile> out;
  if (!zlib_) {
    out.emplace(path);
    out->write(header_);
  }
  blobs_.clear();
  // (The arrays in the layout's order; those not chosen are left out.)
  auto block = [&](VtuLayout::Array a, const void* data, std::uint64_t bytes) {
    if (!present_[a])
      return;
    if (zlib_) {
      blobs_.emplace_back(a, zlib_blocks(data, bytes));
      return;
    }
    out->write(reinterpret_cast<const char*>(&bytes), sizeof bytes);
    out->write(static_cast<const char*>(data), bytes);
  };
  block(VtuLayout::Displacement, disp_.data(), 3 * std::size_t{wn} * sizeof(float));
  block(VtuLayout::Velocity, vel_.data(), 3 * std::size_t{wn} * sizeof(float));
  block(VtuLayout::Stress, stress_f_.data(), 6 * std::size_t{wn} * sizeof(float));
  block(VtuLayout::NodeStrain, node_strain_f_.data(), 6 * std::size_t{wn} * sizeof(float));
  block(VtuLayout::NodeId, node_id_.data(), node_id_.size() * sizeof(std::int32_t));
  block(VtuLayout::Damage, damage_f_.data(), std::size_t{wb} * sizeof(float));
  block(VtuLayout::State, state_.data(), wb);
  block(VtuLayout::Force, force_f_.data(), std::size_t{wb} * sizeof(float));
  block(VtuLayout::Strain, strain_f_.data(), std::size_t{wb} * sizeof(float));
  block(VtuLayout::BarId, bar_id_.data(), bar_id_.size() * sizeof(std::int32_t));
  int law_key = VtuLayout::kArrays; // (vtu_layout's key of the law's q-th array)
  for (std::size_t a : law_states_) {
    law_state_.clear();
    sim.append_bar_states(a, 0, nb_, law_state_);
    law_state_f_.assign(law_state_.begin(), law_state_.end());
    keep_present(law_state_f_, ranks_.bar, 1);
    const std::uint64_t bytes = law_state_f_.size() * sizeof(float);
    if (zlib_) {
      blobs_.emplace_back(law_key++, zlib_blocks(law_state_f_.data(), bytes));
      continue;
    }
    out->write(reinterpret_cast<const char*>(&bytes), sizeof bytes);
    out->write(reinterpret_cast<const char*>(law_state_f_.data()), bytes);
  }
  if (zlib_) {
    const auto stored = [&](int key, std::uint64_t) -> std::uint64_t {
      for (const auto& [k, blob] : blobs_)
        if (k == key)
          return blob.size();
      return static_stored_[key];
    };
    out.emplace(path);
    out->write(vtu_layout(wn, wb, sim, shaped, arrays_, stored).header);
    for (const auto& blob : blobs_)
      out->write(blob.second.data(), blob.second.size());
  }
  out->write(static_block_.data(), static_block_.size());
  out->write(VtuLayout::trailer);
  out->commit();
}

void write_lattice_vtu(const Simulation& sim, const std::string& path) {
  LatticeVtuWriter(sim).write(sim, path);
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
