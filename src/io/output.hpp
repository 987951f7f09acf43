// Writing the output folder: every file is written under a temporary name and renamed into
// place when complete, so a crash never leaves a half-written file under its final name.
#pragma once

#include "solver/simulation.hpp"

#include <cstdint>
#include <functional>
#include <limits>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

namespace ldem {

// A file written to "<path>.part" and renamed to <path> by commit() once complete. A file whose
// write fails (a full disk, say) is never renamed: a whole file's part is removed, a log's is
// cut back to its last complete write (whole rows) and kept for `ldem resume`, and the write
// throws InputError naming it. A whole file dropped without commit() (an error while it was
// being written) is removed; a log is committed by the destructor, so that what was written
// survives an early stop.
class OutputFile {
public:
  enum class Kind { Whole, Log };
  explicit OutputFile(std::string path, Kind kind = Kind::Whole);
  // Continues a log of an interrupted run: its temporary or final version, cut back to
  // `length` bytes (what a checkpoint recorded), then appended to.
  OutputFile(std::string path, std::uint64_t length);
  std::uint64_t size() const { return size_; }
  // A log's FNV-1a hash of every byte it holds (io/checkpoint.hpp): a checkpoint records it, so
  // that a resume knows the file is the one it continues.
  std::uint64_t hash() const { return hash_; }
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  // Each call is a unit (a log's whole rows): a failure keeps the calls that reached the disk.
  void write(const std::string& text);
  void write(const char* data, std::size_t bytes);
  void flush();
  void commit();
  const std::string& path() const { return path_; }

private:
  [[noreturn]] void fail(int err);
  std::string path_, part_;
  Kind kind_ = Kind::Whole;
  std::FILE* f_ = nullptr;
  std::uint64_t size_ = 0;
  std::uint64_t hash_ = 0;
  std::uint64_t flushed_ = 0;       // bytes known to be on disk (the last successful flush)
  std::vector<std::uint64_t> ends_; // where the writes since then end
};

// Writes a whole file at once (temporary name, then rename).
void write_file(const std::string& path, const std::string& text);

// The file a resumed run continues for the log `path`: its temporary version if there is one
// (a run stopped by an error), else the file itself.
std::string log_in_progress(const std::string& path);
// The FNV-1a hash of the first `length` bytes of `path`; nullopt when it is shorter or unread.
std::optional<std::uint64_t> prefix_hash(const std::string& path, std::uint64_t length);

// One VTK XML unstructured grid of the lattice at the current state: nodes at their reference
// positions with displacement and velocity, bars as lines with state (0 intact, 1 softening,
// 2 broken), damage (dissipated energy over Gf A^f, 0 to 1), axial force, the bar law's state
// arrays that it shows (by their names; none for the bilinear law) and, where fields vary, E,
// Gf, e_p, e_r. Raw binary appended data, values in single precision.
void write_lattice_vtu(const Simulation& sim, const std::string& path);

// Where each array of such a file lies: the XML header (which ends where the appended data
// begins), then each array as a 64-bit byte count and its values, then the trailer. Every
// size follows from the node and bar counts, so a file can also be written piece by piece at
// these positions (distributed runs: src/parallel/snapshot.hpp).
struct VtuLayout {
  enum Array {
    Displacement, // Float32 x 3 per node
    Velocity,     // Float32 x 3 per node
    Stress,       // Float32 x 6 per node (xx, yy, zz, xy, yz, xz), only when named
    NodeStrain,   // Float32 x 6 per node, likewise
    Damage,       // Float32 per bar
    State,        // UInt8 per bar
    Force,        // Float32 per bar
    Strain,       // Float32 per bar
    E,            // Float32 per bar, the four fields only where they vary
    Gf,
    EP,
    ER,
    Points,       // Float32 x 3 per node
    Connectivity, // Int32 x 2 per bar
    Offsets,      // Int32 per bar
    Types,        // UInt8 per bar
    NodeId,       // Int32 per node: its number in the body (a shaped body's snapshots only)
    BarId,        // Int32 per bar: likewise
    kArrays
  };
  std::string header;
  bool present[kArrays] = {};
  std::uint64_t at[kArrays] = {};    // file position of the array's byte count
  std::uint64_t bytes[kArrays] = {}; // the count
  // The bar law's state arrays that the snapshots carry (StateArray::in_snapshots), Float32 per
  // bar after the axial force, each under its name: its index among the law's state arrays
  // (Simulation::bar_state_arrays) and the file position of its byte count.
  std::vector<std::size_t> states;
  std::vector<std::uint64_t> state_at;
  std::uint64_t size = 0; // of the whole file
  static constexpr const char* trailer = "\n</AppendedData>\n</VTKFile>\n";
  // The position of the first byte of value `index` of an array of `width`-byte values.
  std::uint64_t value_at(Array a, std::uint64_t index, std::uint64_t width) const {
    return at[a] + sizeof(std::uint64_t) + index * width;
  }
  std::uint64_t state_value_at(std::size_t s, std::uint64_t index) const {
    return state_at[s] + sizeof(std::uint64_t) + index * sizeof(float);
  }
};
// The arrays a snapshot may hold, by the names they have in it (output.vtu_arrays chooses among
// them): displacement and velocity per node; damage, state, axial_force and strain per bar; the
// bar law's state arrays that snapshots carry; the material fields E, Gf, e_p and e_r (where the
// material varies); and, only where output.vtu_arrays names them, the stress and the strain at
// the nodes ("stress", "node_strain": node_stresses, node_strains). The reference positions, the cells and a shaped body's node and bar numbers
// are always written.
std::vector<std::string> vtu_array_names(std::span<const StateArray> law_states);
// The layout of a snapshot of `sim`'s body (`nodes` and `bars`: the whole body's present ones):
// the arrays `arrays` names (empty: all of vtu_array_names), the fields only where the material
// varies, and with `ids` (a shaped body) each node's and bar's number in the body. With
// `compressed`, the file is zlib-compressed (vtkZLibDataCompressor) and compressed(key, bytes)
// gives the bytes an array of `bytes` takes in the appended data (its block header included);
// key: its VtuLayout::Array, or kArrays + q for the q-th law state array written. The layout's
// `at`, `bytes` and `size` are then those of the stored arrays, for this one snapshot.
using VtuStoredSize = std::function<std::uint64_t(int key, std::uint64_t bytes)>;
VtuLayout vtu_layout(index_t nodes, index_t bars, const Simulation& sim, bool ids = false,
                     const std::vector<std::string>& arrays = {},
                     const VtuStoredSize& compressed = nullptr);
// `bytes` of data as VTK's zlib-compressed appended data: the block header (UInt64: the number
// of blocks of 32768 bytes, that size, the last block's size if partial, else 0, each block's
// compressed size) and the blocks, each compressed on its own (zlib level 1), in parallel.
std::string zlib_blocks(const void* data, std::uint64_t bytes);
constexpr std::uint64_t kZlibBlock = 32768; // VTK's own block size
// The blocks of `bytes` of data, kZlibBlock each (the last what is left), compressed on their
// own as zlib_blocks compresses them, in parallel; `data` starts a block.
std::vector<std::string> zlib_compress_blocks(const void* data, std::uint64_t bytes);
// zlib_blocks' header of an array of `bytes` whose blocks take `sizes` bytes compressed.
std::string zlib_header(std::uint64_t bytes, const std::vector<std::uint64_t>& sizes);

// A shaped body's modules as a NumPy .npy file (body.npy of a run folder): uint8, shape
// (nx, ny, nz), indexed [i, j, k], 1 where the module is present (Fortran order: i fastest, the
// lattice's own). `ldem` reads it back as a [[geometry]] mask.
std::string module_mask_npy(const Lattice& lattice);

// Where a shaped body's present nodes and bars lie in its snapshots, which hold only them, in
// the body's order: node n at node[n] (the present nodes before it), likewise bars; one entry
// more than the items, so that node[n + 1] > node[n] says that n is present. Empty for a box.
struct PresentRanks {
  std::vector<index_t> node, bar;
  explicit PresentRanks(const Lattice& lattice);
  bool shaped() const { return !node.empty(); }
};

// The same for a series of snapshots of one run: what does not change (reference positions,
// connectivity, material fields, the XML header with every offset) is prepared once, so a
// snapshot only converts and writes the displacements, velocities and bar values.
class LatticeVtuWriter {
public:
  // `arrays`: the optional arrays to write (vtu_array_names; empty: all); `zlib`: compressed.
  explicit LatticeVtuWriter(const Simulation& sim, const std::vector<std::string>& arrays = {},
                            bool zlib = false);
  void write(const Simulation& sim, const std::string& path);

private:
  index_t nn_ = 0, nb_ = 0; // the body's nodes and bars
  PresentRanks ranks_;      // of a shaped body, whose snapshots hold its present ones only
  std::vector<std::int32_t> node_id_, bar_id_;
  std::string header_;
  std::vector<char> static_block_;
  std::vector<float> disp_, vel_, damage_f_, force_f_, strain_f_, stress_f_, node_strain_f_;
  std::vector<Vec3> u_all_;    // every node's displacement, for the stress and strain
  std::vector<double> module_, tensor_; // the stress or strain of every module, of every node
  std::vector<std::uint8_t> state_;
  std::vector<double> damage_, force_, strain_;
  std::vector<std::size_t> law_states_; // the law's state arrays written (VtuLayout::states)
  bool present_[VtuLayout::kArrays] = {}; // the arrays written (VtuLayout::present)
  // Compressed snapshots: the choice of arrays, and each static array's stored size (by
  // VtuLayout::Array); the per-snapshot arrays compressed into `blobs_` (by key, as
  // vtu_layout's).
  bool zlib_ = false;
  std::vector<std::string> arrays_;
  std::uint64_t static_stored_[VtuLayout::kArrays] = {};
  std::vector<std::pair<int, std::string>> blobs_;
  std::vector<double> law_state_;
  std::vector<float> law_state_f_;
};
// The stress at each node [Pa] (docs/model.md, "Stress at the nodes"): the mean of the stresses
// of the present modules that have the node (a centre node: its module's), a module's stress
// being its bars' virial over its volume, (1 / L^3) sum_b w_b F_b l_b n_b n_b^T, with each bar's
// share w_b: 1 for a diagonal, 1/2 for a centre-centre bar, 1 / (present modules sharing it)
// for an edge bar. `u`: the displacement of every node, `force`: every bar's axial force
// (Simulation::bar_snapshot). Into `out`, 6 per node in VTK's order of a symmetric tensor: xx,
// yy, zz, xy, yz, xz (0 at a node of no present module).
void node_stresses(const Lattice& lat, const std::vector<Vec3>& u, const std::vector<double>& force,
                   std::vector<double>& out);
// The strain at each node (docs/model.md, "Stress and strain at the nodes"): the mean of the
// strains of the present modules that have the node (a centre node: its module's), a module's
// strain being its mean displacement gradient G, symmetrised, (G + G^T) / 2, with
// G_pq = (1 / 4 L) sum over its 4 edges along q of the difference of u_p from end to end (the
// volume mean of grad u under the trilinear interpolation of its corners' displacements: exact
// for an affine field). Same order as the stress (xx, yy, zz, xy, yz, xz), tensor components.
void node_strains(const Lattice& lat, const std::vector<Vec3>& u, std::vector<double>& out);

// The two passes of node_stresses and node_strains, for a body split over processes: the
// modules of rows [j0, j1) along y in planes [k0, k1) along z (all i; the default, every
// module), and the nodes' means once every module around them is known.
struct ModuleBox {
  index_t j0 = 0, j1 = std::numeric_limits<index_t>::max();
  index_t k0 = 0, k1 = std::numeric_limits<index_t>::max();
};
// Each present module's stress in `box`, 6 per module of the lattice in `module` (sized 6 per
// module; the values of other modules are left as they are).
void module_stresses(const Lattice& lat, const std::vector<Vec3>& u,
                     const std::vector<double>& force, std::vector<double>& module,
                     ModuleBox box = {});
// The same for the strain.
void module_strains(const Lattice& lat, const std::vector<Vec3>& u, std::vector<double>& module,
                    ModuleBox box = {});
// Into `out` (6 per node): a corner node's mean of the present modules that have it, a centre
// node its module's, 0 at a node of no present module.
void node_means(const Lattice& lat, const std::vector<double>& module, std::vector<double>& out);

// The ParaView collection that lists the snapshots.
std::string lattice_pvd(const std::vector<std::pair<double, std::string>>& snapshots);

} // namespace ldem
