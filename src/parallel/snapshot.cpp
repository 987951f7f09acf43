#include "parallel/snapshot.hpp"

#include "parallel/comm.hpp"

#include <algorithm>
#include <cstring>
#include <optional>
#include <stdexcept>

namespace ldem {

SubdomainVtuWriter::SubdomainVtuWriter(const SubdomainRun& run, const Lattice& whole,
                                       const std::vector<std::string>& arrays, bool zlib)
    : whole_(whole), ranks_(whole),
      layout_(vtu_layout(static_cast<index_t>(whole.num_present_nodes()),
                         static_cast<index_t>(whole.num_present_bars()), run.sim(),
                         ranks_.shaped(), arrays)),
      arrays_(arrays), zlib_(zlib), nodes_(subdomain_node_spans(run.subdomain(), whole, true)),
      bars_(subdomain_bar_spans(run.subdomain(), whole, true)) {}

namespace {

// Fills `buf` with the items q of `picks` (per_item values of type T each, from put(q,
// destination)), one after the other.
template <class T, class Put>
void fill(std::vector<char>& buf, const std::vector<index_t>& picks, int per_item, Put&& put) {
  buf.resize(sizeof(T) * per_item * picks.size());
  auto* out = reinterpret_cast<T*>(buf.data());
  for (std::size_t p = 0; p < picks.size(); ++p)
    put(picks[p], out + p * per_item);
}

// The items of span s that the file holds (a shaped body's present ones, else all), as offsets
// in the span, and the place of the first of them in the file's numbering.
index_t picks_of(const Span& s, const std::vector<index_t>& ranks, std::vector<index_t>& picks) {
  picks.clear();
  for (index_t q = 0; q < s.count; ++q)
    if (ranks.empty() || ranks[s.global_first + q + 1] > ranks[s.global_first + q])
      picks.push_back(q);
  return ranks.empty() ? s.global_first : ranks[s.global_first];
}

// The arrays that do not change during a run: the material fields, the points, the cells and
// a shaped body's node and bar numbers (VtuLayout's order puts them last).
bool is_static(int key) {
  return key >= VtuLayout::E && key < VtuLayout::kArrays;
}

} // namespace

std::uint64_t SubdomainVtuWriter::ZlibShare::stored() const {
  std::uint64_t s = sizeof(std::uint64_t) * (3 + sizes.size());
  for (const std::uint64_t b : sizes)
    s += b;
  return s;
}

SubdomainVtuWriter::ZlibShare SubdomainVtuWriter::compress(const std::vector<Piece>& pieces,
                                                           std::uint64_t bytes) {
  // Process r compresses blocks [firsts[r], firsts[r + 1]): consecutive shares of the blocks.
  const auto ranks = static_cast<std::uint64_t>(process_count());
  const auto me = static_cast<std::size_t>(process_rank());
  const std::uint64_t blocks = (bytes + kZlibBlock - 1) / kZlibBlock;
  std::vector<std::uint64_t> firsts(ranks + 1);
  for (std::uint64_t r = 0; r <= ranks; ++r)
    firsts[r] = blocks * r / ranks;
  const auto byte_end = [&](std::size_t r) { return std::min(firsts[r + 1] * kZlibBlock, bytes); };
  // Each piece to the processes whose blocks it falls in: (position, length, bytes) each.
  std::vector<std::string> out(ranks);
  const auto append = [](std::string& s, std::uint64_t v) {
    s.append(reinterpret_cast<const char*>(&v), sizeof v);
  };
  for (const Piece& p : pieces)
    for (std::uint64_t at = p.at, end = p.at + p.bytes.size(); at < end;) {
      const auto r = static_cast<std::size_t>(
          std::upper_bound(firsts.begin(), firsts.end(), at / kZlibBlock) - firsts.begin() - 1);
      const std::uint64_t n = std::min(end, byte_end(r)) - at;
      append(out[r], at);
      append(out[r], n);
      out[r].append(p.bytes, at - p.at, n);
      at += n;
    }
  const std::vector<std::string> in = exchange_bytes(out);
  const std::uint64_t lo = firsts[me] * kZlibBlock, hi = byte_end(me);
  std::string data(hi > lo ? hi - lo : 0, '\0');
  std::uint64_t got = 0;
  for (const std::string& m : in)
    for (std::size_t c = 0; c < m.size();) {
      std::uint64_t at = 0, n = 0;
      std::memcpy(&at, m.data() + c, sizeof at);
      std::memcpy(&n, m.data() + c + sizeof at, sizeof n);
      c += 2 * sizeof(std::uint64_t);
      if (at < lo || at + n > hi)
        throw std::logic_error("compressed snapshot: a piece outside its blocks");
      std::memcpy(data.data() + (at - lo), m.data() + c, n);
      c += n;
      got += n;
    }
  if (got != data.size()) // the owned spans of the processes cover every array once
    throw std::logic_error("compressed snapshot: the pieces do not cover the blocks");
  ZlibShare share;
  share.bytes = bytes;
  share.first = firsts[me];
  std::vector<std::uint64_t> sizes;
  for (const std::string& b : zlib_compress_blocks(data.data(), data.size())) {
    sizes.push_back(b.size());
    share.mine += b;
  }
  share.sizes = gather_on_all(sizes);
  return share;
}

void SubdomainVtuWriter::node_tensors(const SubdomainRun& run, bool stress) {
  const Simulation& sim = run.sim();
  const Lattice& local = sim.lattice();
  const Subdomain& sub = run.subdomain();
  // The owned modules, then the neighbours' ghost modules through the halo exchange (each
  // module's 6 values, 3 at a time, at its centre node), then the means at the nodes.
  module_.assign(6 * std::size_t{local.num_modules()}, 0.0);
  const ModuleBox owned{sub.y.m0 - sub.y.w0, sub.y.m1 - sub.y.w0, sub.z.m0 - sub.z.w0,
                        sub.z.m1 - sub.z.w0};
  if (stress)
    module_stresses(local, u_all_, force_, module_, owned);
  else
    module_strains(local, u_all_, module_, owned);
  const index_t corners = local.num_corners();
  for (std::size_t half = 0; half < 2; ++half) {
    halo_values_.assign(3 * std::size_t{local.num_nodes()}, 0.0);
    for (std::size_t m = 0; m < local.num_modules(); ++m)
      std::copy_n(&module_[6 * m + 3 * half], 3, &halo_values_[3 * (corners + m)]);
    exchange_halos(run, halo_values_, halo_);
    for (std::size_t m = 0; m < local.num_modules(); ++m)
      std::copy_n(&halo_values_[3 * (corners + m)], 3, &module_[6 * m + 3 * half]);
  }
  node_means(local, module_, stress ? stress_ : node_strain_);
}

void SubdomainVtuWriter::write(const SubdomainRun& run, const std::string& path) {
  const VtuLayout& l = layout_;
  std::optional<SharedFile> file;
  if (!zlib_) {
    file.emplace(path);
    if (process_rank() == 0) { // the header, every array's byte count, the trailer
      file->write_at(0, l.header.data(), l.header.size());
      for (int a = 0; a < VtuLayout::kArrays; ++a)
        if (l.present[a])
          file->write_at(l.at[a], &l.bytes[a], sizeof l.bytes[a]);
      const std::uint64_t state_bytes = 4ull * whole_.num_present_bars();
      for (const std::uint64_t at : l.state_at)
        file->write_at(at, &state_bytes, sizeof state_bytes);
      const std::size_t n = std::strlen(VtuLayout::trailer);
      file->write_at(l.size - n, VtuLayout::trailer, n);
    }
  }
  const Simulation& sim = run.sim();
  // Whether array `key` is written now: chosen, and compressed already if it does not change.
  const auto wanted = [&](int key) {
    return (key >= VtuLayout::kArrays || l.present[key]) &&
           !(zlib_ && is_static(key) && shares_.count(key) > 0);
  };
  // buf_ holds the values of the file's items [first, ...) of array `key`, `width` bytes each.
  const auto put = [&](int key, index_t first, std::size_t width) {
    if (!wanted(key))
      return;
    if (zlib_) {
      pieces_[key].push_back({std::uint64_t{first} * width, std::string(buf_.begin(), buf_.end())});
      return;
    }
    file->write_at(key < VtuLayout::kArrays
                       ? l.value_at(static_cast<VtuLayout::Array>(key), first, width)
                       : l.state_value_at(static_cast<std::size_t>(key - VtuLayout::kArrays), first),
                   buf_.data(), buf_.size());
  };
  sim.bar_snapshot(state_, damage_, force_, &strain_);
  // The stress and strain at the nodes need every window node's displacement.
  const bool stress = l.present[VtuLayout::Stress], node_strain = l.present[VtuLayout::NodeStrain];
  if (stress || node_strain) {
    const index_t nn = sim.lattice().num_nodes();
    u_all_.resize(nn);
    v_all_.resize(nn);
    sim.node_states(0, nn, u_all_.data(), v_all_.data());
    if (stress)
      node_tensors(run, true);
    if (node_strain)
      node_tensors(run, false);
  }
  // Nodes: displacement, velocity and reference position, as LatticeVtuWriter converts them.
  auto vec3 = [](float* o, Vec3 v) {
    o[0] = static_cast<float>(v.x);
    o[1] = static_cast<float>(v.y);
    o[2] = static_cast<float>(v.z);
  };
  for (const Span& s : nodes_) {
    const index_t first = picks_of(s, ranks_.node, picks_);
    u_.resize(s.count);
    v_.resize(s.count);
    sim.node_states(s.local_first, s.count, u_.data(), v_.data());
    for (const bool velocity : {false, true}) {
      fill<float>(buf_, picks_, 3, [&](index_t q, float* o) { vec3(o, velocity ? v_[q] : u_[q]); });
      put(velocity ? VtuLayout::Velocity : VtuLayout::Displacement, first, 12);
    }
    for (const auto& [key, tensor] :
         {std::pair{VtuLayout::Stress, &stress_}, std::pair{VtuLayout::NodeStrain, &node_strain_}})
      if (l.present[key]) {
        fill<float>(buf_, picks_, 6, [&](index_t q, float* o) {
          for (std::size_t c = 0; c < 6; ++c)
            o[c] = static_cast<float>((*tensor)[6 * (std::size_t{s.local_first} + q) + c]);
        });
        put(key, first, 24);
      }
    if (wanted(VtuLayout::Points)) {
      fill<float>(buf_, picks_, 3,
                  [&](index_t q, float* o) { vec3(o, whole_.position(s.global_first + q)); });
      put(VtuLayout::Points, first, 12);
    }
    if (ranks_.shaped() && wanted(VtuLayout::NodeId)) {
      fill<std::int32_t>(buf_, picks_, 1, [&](index_t q, std::int32_t* o) {
        *o = static_cast<std::int32_t>(s.global_first + q);
      });
      put(VtuLayout::NodeId, first, 4);
    }
  }
  // Bars: the window's states, damage and forces (owned bars taken), connectivity in the
  // body's node numbers, and the material fields where they vary.
  const bool fields = wanted(VtuLayout::E) || wanted(VtuLayout::Gf) || wanted(VtuLayout::EP) ||
                      wanted(VtuLayout::ER);
  for (const Span& s : bars_) {
    const index_t lb = s.local_first, gb = s.global_first;
    const index_t first = picks_of(s, ranks_.bar, picks_);
    fill<float>(buf_, picks_, 1,
                [&](index_t q, float* o) { *o = static_cast<float>(damage_[lb + q]); });
    put(VtuLayout::Damage, first, 4);
    fill<std::uint8_t>(buf_, picks_, 1, [&](index_t q, std::uint8_t* o) { *o = state_[lb + q]; });
    put(VtuLayout::State, first, 1);
    fill<float>(buf_, picks_, 1,
                [&](index_t q, float* o) { *o = static_cast<float>(force_[lb + q]); });
    put(VtuLayout::Force, first, 4);
    fill<float>(buf_, picks_, 1,
                [&](index_t q, float* o) { *o = static_cast<float>(strain_[lb + q]); });
    put(VtuLayout::Strain, first, 4);
    for (std::size_t q = 0; q < l.states.size(); ++q) {
      law_state_.clear();
      sim.append_bar_states(l.states[q], lb, s.count, law_state_);
      fill<float>(buf_, picks_, 1,
                  [&](index_t i, float* o) { *o = static_cast<float>(law_state_[i]); });
      put(VtuLayout::kArrays + static_cast<int>(q), first, 4);
    }
    if (fields) {
      const Lattice& local = sim.lattice();
      const BarTable& table = sim.table();
      fill<float>(buf_, picks_, 1, [&](index_t q, float* o) {
        *o = static_cast<float>(table.properties(local, lb + q).E);
      });
      put(VtuLayout::E, first, 4);
      fill<float>(buf_, picks_, 1, [&](index_t q, float* o) {
        *o = static_cast<float>(table.properties(local, lb + q).Gf);
      });
      put(VtuLayout::Gf, first, 4);
      fill<float>(buf_, picks_, 1,
                  [&](index_t q, float* o) { *o = static_cast<float>(table.e_p_bar()[lb + q]); });
      put(VtuLayout::EP, first, 4);
      fill<float>(buf_, picks_, 1,
                  [&](index_t q, float* o) { *o = static_cast<float>(table.e_r_bar()[lb + q]); });
      put(VtuLayout::ER, first, 4);
    }
    if (wanted(VtuLayout::Connectivity)) {
      fill<std::int32_t>(buf_, picks_, 2, [&](index_t q, std::int32_t* o) {
        const auto nodes = whole_.bar_nodes(gb + q);
        for (int e = 0; e < 2; ++e)
          o[e] = static_cast<std::int32_t>(ranks_.shaped() ? ranks_.node[nodes[e]] : nodes[e]);
      });
      put(VtuLayout::Connectivity, first, 8);
    }
    if (wanted(VtuLayout::Offsets)) {
      fill<std::int32_t>(buf_, picks_, 1, [&](index_t q, std::int32_t* o) {
        const index_t b = ranks_.shaped() ? ranks_.bar[gb + q] : gb + q; // the file's number
        *o = static_cast<std::int32_t>(2 * (std::int64_t{b} + 1));
      });
      put(VtuLayout::Offsets, first, 4);
    }
    if (wanted(VtuLayout::Types)) {
      fill<std::uint8_t>(buf_, picks_, 1, [](index_t, std::uint8_t* o) { *o = 3; }); // VTK_LINE
      put(VtuLayout::Types, first, 1);
    }
    if (ranks_.shaped() && wanted(VtuLayout::BarId)) {
      fill<std::int32_t>(buf_, picks_, 1, [&](index_t q, std::int32_t* o) {
        *o = static_cast<std::int32_t>(gb + q);
      });
      put(VtuLayout::BarId, first, 4);
    }
  }
  if (zlib_) {
    write_compressed(run, path);
    return;
  }
  file->commit();
}

void SubdomainVtuWriter::write_compressed(const SubdomainRun& run, const std::string& path) {
  const VtuLayout& l = layout_;
  // Every array written, in a fixed order (the same on every process): compressed in shares.
  std::vector<int> keys;
  for (int a = 0; a < VtuLayout::kArrays; ++a)
    if (l.present[a])
      keys.push_back(a);
  for (std::size_t q = 0; q < l.states.size(); ++q)
    keys.push_back(VtuLayout::kArrays + static_cast<int>(q));
  for (const int key : keys) {
    if (is_static(key) && shares_.count(key) > 0)
      continue;
    const std::uint64_t bytes =
        key < VtuLayout::kArrays ? l.bytes[key] : 4ull * whole_.num_present_bars();
    shares_[key] = compress(pieces_[key], bytes);
    pieces_[key].clear();
  }
  // The compressed sizes place the arrays: the header, then each array's block header (the
  // first process) and each process's blocks.
  const auto nodes = static_cast<index_t>(whole_.num_present_nodes()),
             bars = static_cast<index_t>(whole_.num_present_bars());
  const VtuLayout z = vtu_layout(nodes, bars, run.sim(), ranks_.shaped(), arrays_,
                                 [&](int key, std::uint64_t) { return shares_.at(key).stored(); });
  SharedFile file(path);
  for (const int key : keys) {
    const ZlibShare& s = shares_.at(key);
    const std::uint64_t at = key < VtuLayout::kArrays
                                 ? z.at[key]
                                 : z.state_at[static_cast<std::size_t>(key - VtuLayout::kArrays)];
    const std::uint64_t head = sizeof(std::uint64_t) * (3 + s.sizes.size());
    if (process_rank() == 0) {
      const std::string h = zlib_header(s.bytes, s.sizes);
      file.write_at(at, h.data(), h.size());
    }
    std::uint64_t before = 0; // the blocks of the processes before this one
    for (std::uint64_t b = 0; b < s.first; ++b)
      before += s.sizes[b];
    if (!s.mine.empty())
      file.write_at(at + head + before, s.mine.data(), s.mine.size());
  }
  if (process_rank() == 0) {
    file.write_at(0, z.header.data(), z.header.size());
    const std::size_t n = std::strlen(VtuLayout::trailer);
    file.write_at(z.size - n, VtuLayout::trailer, n);
  }
  file.commit();
}

} // namespace ldem
