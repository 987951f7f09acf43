#include "parallel/snapshot.hpp"

#include "parallel/comm.hpp"

#include <cstring>

namespace ldem {

SubdomainVtuWriter::SubdomainVtuWriter(const SubdomainRun& run, const Lattice& whole,
                                       const std::vector<std::string>& arrays)
    : whole_(whole), ranks_(whole),
      layout_(vtu_layout(static_cast<index_t>(whole.num_present_nodes()),
                         static_cast<index_t>(whole.num_present_bars()), run.sim(),
                         ranks_.shaped(), arrays)),
      nodes_(subdomain_node_spans(run.subdomain(), whole, true)),
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

} // namespace

void SubdomainVtuWriter::write(const SubdomainRun& run, const std::string& path) {
  SharedFile file(path);
  const VtuLayout& l = layout_;
  if (process_rank() == 0) { // the header, every array's byte count, the trailer
    file.write_at(0, l.header.data(), l.header.size());
    for (int a = 0; a < VtuLayout::kArrays; ++a)
      if (l.present[a])
        file.write_at(l.at[a], &l.bytes[a], sizeof l.bytes[a]);
    const std::uint64_t state_bytes = 4ull * whole_.num_present_bars();
    for (const std::uint64_t at : l.state_at)
      file.write_at(at, &state_bytes, sizeof state_bytes);
    const std::size_t n = std::strlen(VtuLayout::trailer);
    file.write_at(l.size - n, VtuLayout::trailer, n);
  }
  const Simulation& sim = run.sim();
  index_t first = 0; // the file's number of the span's first item written
  auto put = [&](VtuLayout::Array a, const Span&, std::size_t width) {
    if (l.present[a]) // (an array output.vtu_arrays leaves out: not written)
      file.write_at(l.value_at(a, first, width), buf_.data(), buf_.size());
  };
  // Nodes: displacement, velocity and reference position, as LatticeVtuWriter converts them.
  auto vec3 = [](float* o, Vec3 v) {
    o[0] = static_cast<float>(v.x);
    o[1] = static_cast<float>(v.y);
    o[2] = static_cast<float>(v.z);
  };
  for (const Span& s : nodes_) {
    first = picks_of(s, ranks_.node, picks_);
    u_.resize(s.count);
    v_.resize(s.count);
    sim.node_states(s.local_first, s.count, u_.data(), v_.data());
    for (const bool velocity : {false, true}) {
      fill<float>(buf_, picks_, 3, [&](index_t q, float* o) { vec3(o, velocity ? v_[q] : u_[q]); });
      put(velocity ? VtuLayout::Velocity : VtuLayout::Displacement, s, 12);
    }
    fill<float>(buf_, picks_, 3,
                [&](index_t q, float* o) { vec3(o, whole_.position(s.global_first + q)); });
    put(VtuLayout::Points, s, 12);
    if (ranks_.shaped()) {
      fill<std::int32_t>(buf_, picks_, 1, [&](index_t q, std::int32_t* o) {
        *o = static_cast<std::int32_t>(s.global_first + q);
      });
      put(VtuLayout::NodeId, s, 4);
    }
  }
  // Bars: the window's states, damage and forces (owned bars taken), connectivity in the
  // body's node numbers, and the material fields where they vary.
  sim.bar_snapshot(state_, damage_, force_, &strain_);
  const bool fields = l.present[VtuLayout::E] || l.present[VtuLayout::Gf] ||
                      l.present[VtuLayout::EP] || l.present[VtuLayout::ER];
  for (const Span& s : bars_) {
    const index_t lb = s.local_first, gb = s.global_first;
    first = picks_of(s, ranks_.bar, picks_);
    fill<float>(buf_, picks_, 1,
                [&](index_t q, float* o) { *o = static_cast<float>(damage_[lb + q]); });
    put(VtuLayout::Damage, s, 4);
    fill<std::uint8_t>(buf_, picks_, 1, [&](index_t q, std::uint8_t* o) { *o = state_[lb + q]; });
    put(VtuLayout::State, s, 1);
    fill<float>(buf_, picks_, 1,
                [&](index_t q, float* o) { *o = static_cast<float>(force_[lb + q]); });
    put(VtuLayout::Force, s, 4);
    fill<float>(buf_, picks_, 1,
                [&](index_t q, float* o) { *o = static_cast<float>(strain_[lb + q]); });
    put(VtuLayout::Strain, s, 4);
    for (std::size_t q = 0; q < l.states.size(); ++q) {
      law_state_.clear();
      sim.append_bar_states(l.states[q], lb, s.count, law_state_);
      fill<float>(buf_, picks_, 1,
                  [&](index_t i, float* o) { *o = static_cast<float>(law_state_[i]); });
      file.write_at(l.state_value_at(q, first), buf_.data(), buf_.size());
    }
    if (fields) {
      const Lattice& local = sim.lattice();
      const BarTable& table = sim.table();
      fill<float>(buf_, picks_, 1, [&](index_t q, float* o) {
        *o = static_cast<float>(table.properties(local, lb + q).E);
      });
      put(VtuLayout::E, s, 4);
      fill<float>(buf_, picks_, 1, [&](index_t q, float* o) {
        *o = static_cast<float>(table.properties(local, lb + q).Gf);
      });
      put(VtuLayout::Gf, s, 4);
      fill<float>(buf_, picks_, 1,
                  [&](index_t q, float* o) { *o = static_cast<float>(table.e_p_bar()[lb + q]); });
      put(VtuLayout::EP, s, 4);
      fill<float>(buf_, picks_, 1,
                  [&](index_t q, float* o) { *o = static_cast<float>(table.e_r_bar()[lb + q]); });
      put(VtuLayout::ER, s, 4);
    }
    fill<std::int32_t>(buf_, picks_, 2, [&](index_t q, std::int32_t* o) {
      const auto nodes = whole_.bar_nodes(gb + q);
      for (int e = 0; e < 2; ++e)
        o[e] = static_cast<std::int32_t>(ranks_.shaped() ? ranks_.node[nodes[e]] : nodes[e]);
    });
    put(VtuLayout::Connectivity, s, 8);
    fill<std::int32_t>(buf_, picks_, 1, [&](index_t q, std::int32_t* o) {
      const index_t b = ranks_.shaped() ? ranks_.bar[gb + q] : gb + q; // the file's number
      *o = static_cast<std::int32_t>(2 * (std::int64_t{b} + 1));
    });
    put(VtuLayout::Offsets, s, 4);
    fill<std::uint8_t>(buf_, picks_, 1, [](index_t, std::uint8_t* o) { *o = 3; }); // VTK_LINE
    put(VtuLayout::Types, s, 1);
    if (ranks_.shaped()) {
      fill<std::int32_t>(buf_, picks_, 1, [&](index_t q, std::int32_t* o) {
        *o = static_cast<std::int32_t>(gb + q);
      });
      put(VtuLayout::BarId, s, 4);
    }
  }
  file.commit();
}

} // namespace ldem
