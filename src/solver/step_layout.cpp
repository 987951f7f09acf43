#include "solver/step_layout.hpp"

#include "util/aligned.hpp"

#include <cmath>
#include <limits>
#include <unordered_map>

namespace ldem {

std::size_t StepLayout::node_row_of(const Lattice& lat, index_t node) const {
  const NodeAddress a = lat.node_address(node);
  // Line (j, k) holds its corner row, then its centre row if it has one.
  return lines[a.j + (lat.ny() + 1ull) * a.k].node_begin + (a.centre ? 1 : 0);
}

namespace {

// Whether the bar pass may leave a row's absent bars out (BarRow::p0, p1): the AVX-512 node
// kernel reads a bar's force only where the bar is present; the portable one reads the whole
// ranges of its links from the plane buffers.
#if defined(__AVX512F__)
constexpr bool kTrimRows = true;
#else
constexpr bool kTrimRows = false;
#endif

// A hash of `count` bytes and a seed (FNV-1a, then mixed): to find rows kept with the same
// bytes, which are then compared.
std::uint64_t hash_bytes(const std::uint8_t* p, std::size_t count, std::uint64_t seed) {
  std::uint64_t h = 0xcbf29ce484222325ull ^ (seed * 0x9E3779B97F4A7C15ull);
  for (std::size_t i = 0; i < count; ++i)
    h = (h ^ p[i]) * 0x100000001b3ull;
  return h ^ (h >> 29);
}

// A shaped body's node row r (of n nodes and nl links): its vectors of 8 nodes whose every
// lane has every link at area factor 1 (the longest run of them, [lo, hi)) and, for the others
// in order, each link's lanes: the present bars and their area factors from the bars' codes.
void add_row_span(StepLayout& out, std::size_t r, const RowLink* links, int nl, std::int64_t n,
                  std::unordered_multimap<std::uint64_t, std::size_t>& seen) {
  const auto lanes_of = [&](const RowLink& L, std::int64_t i) {
    EdgeLanes e{0, 0, 0, 0, 0, 0};
    for (std::int64_t q = std::max<std::int64_t>(L.ilo, i);
         q < std::min<std::int64_t>(L.ihi, i + 8); ++q) {
      const auto bit = static_cast<std::uint8_t>(1u << (q - i));
      switch (out.bar_code[static_cast<std::size_t>(L.bar_base + q)]) {
      case 0:
        continue;
      case 1:
        e.q1 |= bit;
        break;
      case 2:
        e.q2 |= bit;
        break;
      case 3:
        e.q3 |= bit;
        break;
      default:
        break;
      }
      e.has |= bit;
    }
    return e;
  };
  const auto clean = [&](std::int64_t i) {
    if (nl < 7 || i + 8 > n)
      return false;
    for (int l = 0; l < nl; ++l) {
      const EdgeLanes e = lanes_of(links[l], i);
      if (e.has != 0xFF || (e.q1 | e.q2 | e.q3) != 0)
        return false;
    }
    return true;
  };
  std::int64_t lo = 0, hi = 0;
  for (std::int64_t i = 0; i < n;) {
    if (!clean(i)) {
      i += 8;
      continue;
    }
    std::int64_t e = i + 8;
    while (e < n && clean(e))
      e += 8;
    if (e - i > hi - lo) {
      lo = i;
      hi = e;
    }
    i = e;
  }
  // The vectors that hold present nodes (a present node has a present bar on some link).
  std::int64_t from = n, to = 0;
  for (std::int64_t i = 0; i < n; i += 8)
    for (int l = 0; l < nl; ++l)
      if (lanes_of(links[l], i).has != 0) {
        from = std::min(from, i);
        to = i + 8;
      }
  if (from >= to)
    from = to = 0;
  // The masked vectors' lanes; a row whose are the same as an earlier row's shares them (a
  // prism's rows along its axis).
  std::vector<EdgeLanes> lanes;
  for (std::int64_t i = from; i < to; i += 8) {
    if (i >= lo && i + 8 <= hi)
      continue;
    for (int l = 0; l < kMaxRowLinks; ++l)
      lanes.push_back(l < nl ? lanes_of(links[l], i) : EdgeLanes{0, 0, 0, 0, 0, 0});
  }
  const auto* const bytes = reinterpret_cast<const std::uint8_t*>(lanes.data());
  const std::size_t count = lanes.size() * sizeof(EdgeLanes);
  const std::uint64_t key = hash_bytes(bytes, count, count);
  std::size_t begin = out.edge_lanes.size();
  bool found = false;
  for (auto [it, end] = seen.equal_range(key); it != end && !found; ++it)
    if (it->second + lanes.size() <= out.edge_lanes.size() &&
        std::equal(bytes, bytes + count,
                   reinterpret_cast<const std::uint8_t*>(out.edge_lanes.data() + it->second))) {
      begin = it->second;
      found = true;
    }
  if (!found) {
    out.edge_lanes.insert(out.edge_lanes.end(), lanes.begin(), lanes.end());
    seen.emplace(key, begin);
  }
  out.row_span[r] = {n, nl, lo, hi, begin, from, to};
}

// The kinds of node rows and each row's links (link_const, edge_lanes, row_kinds, row_kind,
// link_ref), from the bar rows (in (k, j, family) order, `row_at`).
void build_row_links(StepLayout& out, const Lattice& lat,
                     const std::vector<std::uint32_t>& row_at) {
  const auto same = [](const LinkConst& a, const LinkConst& b) {
    return a.rx == b.rx && a.ry == b.ry && a.rz == b.rz && a.k == b.k && a.l0 == b.l0 &&
           a.kl0 == b.kl0 && a.scale == b.scale && a.inv_lp2 == b.inv_lp2 && a.ilo == b.ilo &&
           a.ihi == b.ihi && a.dk == b.dk && a.first_node == b.first_node;
  };
  out.link_ref.resize(kMaxRowLinks * out.node_rows.size());
  out.row_kind.resize(out.node_rows.size());
  if (out.coded())
    out.row_span.resize(out.node_rows.size());
  std::unordered_multimap<std::uint64_t, std::size_t> spans_seen; // (add_row_span)
  for (std::size_t r = 0; r < out.node_rows.size(); ++r) {
    RowLink links[kMaxRowLinks];
    const int nl = row_links(lat, out.node_rows[r], links, out.slots);
    LinkConst kind[kMaxRowLinks]{};
    const std::int64_t n = out.node_rows[r].length;
    std::int64_t lo = 0, hi = n;
    for (int l = 0; l < nl; ++l) {
      const RowLink& L = links[l];
      const BarAddress a = lat.bar_address(static_cast<index_t>(L.bar_base + L.ilo));
      const std::uint32_t br =
          row_at[(a.k * (lat.ny() + 1ull) + a.j) * kFamilies + static_cast<std::size_t>(a.family)];
      const BarRow& row = out.bar_rows[br];
      const FamilyInfo& fi = lat.family(row.family);
      // (A row whose bars have their own stiffness never takes the fast path: no spring, so
      // that such rows share their kinds.)
      const bool own = row.own_stiffness();
      const double k = row.stiffness;
      const double scale = own ? 1.0 : row.end_factor / row.factor;
      const double inv_lp2 = own ? 0.0 : out.row_inv_lp[br] * out.row_inv_lp[br];
      kind[l] = {L.r0.x,
                 L.r0.y,
                 L.r0.z,
                 k,
                 fi.l0,
                 k * fi.l0,
                 scale,
                 inv_lp2,
                 L.ilo,
                 L.ihi,
                 L.dk,
                 lat.bar_nodes(static_cast<index_t>(L.bar_base + L.ilo))[0] ==
                     out.node_rows[r].first + L.ilo};
      out.link_ref[kMaxRowLinks * r + l] = {L.other_base, br,
                                            static_cast<std::int32_t>(L.plane_base)};
      // A first or last bar with a factor of its own needs its lane scaled.
      const std::int64_t scaled = scale != 1.0 ? 1 : 0;
      lo = std::max(lo, std::int64_t{L.ilo} + scaled);
      hi = std::min(hi, std::int64_t{L.ihi} - scaled);
    }
    std::size_t t = 0;
    while (t < out.row_kinds.size() &&
           !(out.row_kinds[t].n == n && out.row_kinds[t].links == nl &&
             std::equal(kind, kind + nl, &out.link_const[kMaxRowLinks * t], same)))
      ++t;
    if (t == out.row_kinds.size()) {
      // Fewer than 7 links (the corner rows along a box's x edges have 6, rows of a box a
      // module wide fewer): padded to 7 with links no lane has.
      if (nl < 7)
        lo = hi = 0;
      hi = std::max(lo, hi);
      out.row_kinds.push_back({n, nl, lo, hi, out.edge_lanes.size(), 0, n});
      out.link_const.insert(out.link_const.end(), kind, kind + kMaxRowLinks);
      const auto lane = [](std::int64_t at, std::int64_t i) {
        return at >= i && at < i + 8 ? static_cast<std::uint8_t>(1u << (at - i)) : std::uint8_t{0};
      };
      for (std::int64_t i = 0; i < n; i += 8) {
        if (i >= lo && i + 8 <= hi)
          continue;
        for (int l = 0; l < kMaxRowLinks; ++l) {
          const LinkConst& L = kind[l];
          EdgeLanes e{0, 0, 0, 0, 0, 0};
          for (std::int64_t q = std::max(L.ilo, i); q < std::min(L.ihi, i + 8); ++q)
            e.has = static_cast<std::uint8_t>(e.has | (1u << (q - i)));
          if (L.scale != 1.0) {
            e.first = lane(L.ilo, i);
            e.last = lane(L.ihi - 1, i);
          }
          out.edge_lanes.push_back(e);
        }
      }
    }
    out.row_kind[r] = static_cast<std::uint16_t>(t);
    if (out.coded())
      add_row_span(out, r, links, nl, n, spans_seen);
  }
}

// A shaped body's node rows kept to their windows (StepLayout::row_window), the rows one after
// another in the step's order, and the slots the kernels start from moved with them.
void compact_rows(StepLayout& out, const Lattice& lat) {
  const std::size_t nr = out.node_rows.size();
  std::vector<std::array<std::int64_t, 2>> w(nr, {std::numeric_limits<std::int64_t>::max(), 0});
  const auto widen = [&](std::size_t r, std::int64_t a, std::int64_t b) {
    if (a < b)
      w[r] = {std::min(w[r][0], a), std::max(w[r][1], b)};
  };
  for (std::size_t r = 0; r < nr; ++r)
    widen(r, out.row_span[r].from, std::min(out.row_span[r].to, out.row_span[r].n));
  // The nodes of each bar row's bars [p0, p1) (first nodes at a_first + i, second at b_first + i).
  const auto first_node = [&](std::size_t br, int end) {
    const BarRow& row = out.bar_rows[br];
    const FamilyInfo& fi = lat.family(row.family);
    return end == 0 ? fi.a.at(0, row.j, row.k) : fi.b.at(0, row.j, row.k);
  };
  for (std::size_t br = 0; br < out.bar_rows.size(); ++br)
    for (int end = 0; end < 2; ++end) {
      const std::size_t r = out.bar_row_nodes[br][static_cast<std::size_t>(end)];
      const std::int64_t at = first_node(br, end) - out.node_rows[r].first;
      widen(r, out.bar_rows[br].p0 + at, out.bar_rows[br].p1 + at);
    }
  // Whole vectors of 8 from a cache line on; a row starts no earlier than 8 slots past its
  // window's start, so that every row's slot of i = 0 (and of i = -1, where a link starts) is
  // inside the arrays.
  out.row_window.resize(nr);
  out.row_origin.resize(nr);
  std::int64_t at = 8;
  for (std::size_t r = 0; r < nr; ++r) {
    if (w[r][0] >= w[r][1]) {
      out.row_window[r] = {0, 0};
      out.row_origin[r] = 8;
      continue;
    }
    const std::int64_t from = w[r][0] / 8 * 8, to = (w[r][1] + 7) / 8 * 8;
    at = std::max(at, from + 8);
    out.row_window[r] = {from, to};
    out.row_origin[r] = at - from;
    at += to - from;
  }
  out.zero_slot = static_cast<std::size_t>(at);
  out.slot_count = out.zero_slot + round_up_to_line(lat.nx() + 1ull) + 8;
  for (std::size_t br = 0; br < out.bar_rows.size(); ++br) {
    const auto slot0 = [&](int end) {
      const std::size_t r = out.bar_row_nodes[br][static_cast<std::size_t>(end)];
      return static_cast<std::size_t>(out.row_origin[r] + first_node(br, end) -
                                      out.node_rows[r].first);
    };
    out.bar_rows[br].a_slot = slot0(0);
    out.bar_rows[br].b_slot = slot0(1);
  }
  // Each bar row's bars [p0, p1) in the state arrays (from an index no less than p0, so that
  // every row's index of i = 0 is one), then the rows at rest. Their codes likewise, but a row
  // whose codes are already kept (a prism's or cylinder's rows that differ only in their place
  // along its axis) takes them there.
  std::vector<std::uint8_t> code;
  // (p0, p1 and a hash of the codes) -> the origins of the rows kept with them
  std::unordered_multimap<std::uint64_t, std::int64_t> seen;
  out.state_origin.resize(out.bar_rows.size());
  out.code_origin.resize(out.bar_rows.size());
  std::int64_t q = 0;
  for (std::size_t br = 0; br < out.bar_rows.size(); ++br) {
    const BarRow& row = out.bar_rows[br];
    q = std::max<std::int64_t>(q, row.p0);
    out.state_origin[br] = q - row.p0;
    q += row.p1 - row.p0;
    const std::uint8_t* const from =
        out.bar_code.data() + lat.bar(static_cast<Family>(row.family), 0, row.j, row.k) + row.p0;
    const auto len = static_cast<std::size_t>(row.p1 - row.p0);
    const std::uint64_t key = hash_bytes(from, len, (std::uint64_t{row.p0} << 32) | row.p1);
    std::int64_t origin = -1;
    for (auto [it, end] = seen.equal_range(key); it != end && origin < 0; ++it)
      if (it->second + row.p1 <= static_cast<std::int64_t>(code.size()) &&
          std::equal(from, from + len, code.begin() + it->second + row.p0))
        origin = it->second;
    if (origin < 0) {
      const std::int64_t c = std::max<std::int64_t>(static_cast<std::int64_t>(code.size()), row.p0);
      origin = c - row.p0;
      code.resize(static_cast<std::size_t>(c), 0);
      code.insert(code.end(), from, from + len);
      seen.emplace(key, origin);
    }
    out.code_origin[br] = origin;
  }
  out.rest_state = static_cast<std::size_t>(q);
  out.rest_stride = lat.nx() + 9ull; // (a row has at most nx + 1 bars)
  out.state_count = out.rest_state + kFamilies * out.rest_stride;
  code.resize(code.size() + 64, 0); // (a line of zeros after the last row's codes)
  out.bar_code = std::move(code);
  for (std::size_t r = 0; r < nr; ++r) {
    RowLink links[kMaxRowLinks];
    const int nl = row_links(lat, out.node_rows[r], links);
    for (int l = 0; l < nl; ++l) {
      const std::size_t o = out.node_row_of(lat, static_cast<index_t>(links[l].other_base +
                                                                     links[l].ilo));
      out.link_ref[kMaxRowLinks * r + static_cast<std::size_t>(l)].other =
          out.row_origin[o] + (links[l].other_base - out.node_rows[o].first);
    }
  }
}

} // namespace

StepLayout build_step_layout(const Lattice& lat, const BarTable& table,
                             const std::function<double(int, index_t, index_t)>& elastic_limit) {
  StepLayout out;
  // The step loop's node arrays: the lattice's rows of nodes, each from a cache line on.
  out.slots = {static_cast<std::int64_t>(round_up_to_line(lat.nx() + 1ull)),
               static_cast<std::int64_t>(round_up_to_line(lat.nx())), 0};
  out.slots.centre_first = out.slots.corner_row * (lat.ny() + 1ll) * (lat.nz() + 1ll);
  out.slot_count =
      static_cast<std::size_t>(out.slots.centre_first + out.slots.centre_row * lat.ny() * lat.nz());

  // A shaped body of one material: each bar's area factor in quarters (exact: 1/4 steps).
  const bool coded = lat.shaped() && !table.per_bar();
  if (coded) {
    out.bar_code.resize(lat.num_bars());
    for (int f = 0; f < kFamilies; ++f) {
      const FamilyInfo& fi = lat.family(f);
      for (index_t k = 0; k < fi.nk; ++k)
        for (index_t j = 0; j < fi.nj; ++j)
          for (index_t i = 0; i < fi.ni; ++i)
            out.bar_code[static_cast<std::size_t>(fi.offset + i + fi.ni * (j + fi.nj * k))] =
                static_cast<std::uint8_t>(4.0 * lat.area_factor(static_cast<Family>(f), i, j, k));
    }
  }
  // A node row needs bar rows of its own line and the line below, in its plane and the plane
  // below, so the bar forces it reads were computed moments before.
  for (const NodeRow& row : node_rows(lat))
    out.node_rows.push_back(row);
  std::stable_sort(
      out.node_rows.begin(), out.node_rows.end(),
      [](const NodeRow& a, const NodeRow& b) { return a.k != b.k ? a.k < b.k : a.j < b.j; });
  for (index_t k = 0; k <= lat.nz(); ++k)
    for (index_t j = 0; j <= lat.ny(); ++j)
      for (int f = 0; f < kFamilies; ++f) {
        const FamilyInfo& fi = lat.family(f);
        if (k >= fi.nk || j >= fi.nj)
          continue;
        const auto fam = static_cast<Family>(f);
        // Along a row (i running) an edge bar's area factor changes only at i = 0 and
        // i = ni - 1 (EdgeY, EdgeZ: the x faces); inside it is that of i = 1.
        const double inner =
            coded ? 1.0 : lat.area_factor(fam, std::min<index_t>(1, fi.ni - 1), j, k);
        const double end = coded ? 1.0 : lat.area_factor(fam, 0, j, k);
        index_t p0 = 0, p1 = fi.ni;
        if (coded && kTrimRows) {
          // From the vector of 8 of the first present bar (the lanes stay those of the node
          // kernel's vectors) to the last present bar; an empty range where none is.
          const std::uint8_t* code = out.bar_code.data() + fi.offset + fi.ni * (j + fi.nj * k);
          while (p1 > 0 && code[p1 - 1] == 0)
            --p1;
          while (p0 < p1 && code[p0] == 0)
            ++p0;
          p0 = p0 / 8 * 8;
        }
        const index_t b0 = lat.bar(fam, 0, j, k);
        out.bar_rows.push_back({f, j, k, inner, end, out.slot(lat, fi.a.at(0, j, k)),
                                out.slot(lat, fi.b.at(0, j, k)), p0, p1,
                                table.row_stiffness(f, j, k) * inner, elastic_limit(f, b0, fi.ni)});
      }
  // The links of every node row, computed once (they cost more to derive than to read), their
  // bar rows (in (k, j, family) order) and pristine springs; rows of one kind share their
  // constants.
  std::vector<std::uint32_t> row_at((lat.nz() + 1ull) * (lat.ny() + 1ull) * kFamilies, 0);
  out.row_inv_lp.resize(out.bar_rows.size());
  out.row_first_centre.resize(out.bar_rows.size());
  for (std::size_t r = 0; r < out.bar_rows.size(); ++r) {
    const BarRow& row = out.bar_rows[r];
    row_at[(row.k * (lat.ny() + 1ull) + row.j) * kFamilies + static_cast<std::size_t>(row.family)] =
        static_cast<std::uint32_t>(r);
    const double l0 = lat.family(row.family).l0;
    const double e_lim = row.elastic_limit;
    // (A law without an elastic limit: 0, no bar is ever near it.)
    out.row_inv_lp[r] = 1.0 / (l0 * (1.0 + e_lim));
    out.row_first_centre[r] = row.family >= static_cast<int>(Family::CentreX);
  }
  build_row_links(out, lat, row_at);
  // Where the portable kernel can take a whole row in one pass, from the bar pass's buffers: a
  // link missing at a row's end reads a zero pad of the plane buffer (s = 0) and a neighbouring
  // slot's finite displacement, so that holds wherever those reads stay inside the lattice's
  // nodes in its own numbering (all rows but the first corner row and the rows that reach the
  // end of the last centre row), which keeps them inside the slots too (a row's slots start
  // and end no earlier than its nodes do).
  out.row_whole.assign(out.node_rows.size(), 0);
  for (std::size_t r = 0; r < out.node_rows.size(); ++r) {
    RowLink links[kMaxRowLinks];
    const int nl = row_links(lat, out.node_rows[r], links);
    // (A row with fewer than 7 links is padded to 7 with a link that no node has; the whole-row
    // pass would read that link's s from the start of the plane buffer.)
    bool whole = nl >= 7;
    for (int l = 0; l < nl; ++l)
      whole = whole && links[l].other_base >= 0 &&
              links[l].other_base + out.node_rows[r].length <= std::int64_t{lat.num_nodes()};
    out.row_whole[r] = whole;
  }
  // Row ranges of each line (j, k), and the lines of each plane k.
  out.planes.assign(lat.nz() + 1ull, {0, 0});
  std::size_t br = 0, nr = 0;
  for (index_t k = 0; k <= lat.nz(); ++k) {
    out.planes[k].line_begin = out.lines.size();
    for (index_t j = 0; j <= lat.ny(); ++j) {
      Line line{br, br, nr, nr};
      while (line.bar_end < out.bar_rows.size() && out.bar_rows[line.bar_end].k == k &&
             out.bar_rows[line.bar_end].j == j)
        ++line.bar_end;
      while (line.node_end < out.node_rows.size() && out.node_rows[line.node_end].k == k &&
             out.node_rows[line.node_end].j == j)
        ++line.node_end;
      br = line.bar_end;
      nr = line.node_end;
      out.lines.push_back(line);
    }
    out.planes[k].line_end = out.lines.size();
  }
  out.bar_row_nodes.resize(out.bar_rows.size());
  for (std::size_t r = 0; r < out.bar_rows.size(); ++r) {
    const BarRow& row = out.bar_rows[r];
    const FamilyInfo& fi = lat.family(row.family);
    out.bar_row_nodes[r] = {
        static_cast<std::uint32_t>(out.node_row_of(lat, fi.a.at(0, row.j, row.k))),
        static_cast<std::uint32_t>(out.node_row_of(lat, fi.b.at(0, row.j, row.k)))};
  }
  for (const Line& line : out.lines) {
    std::size_t n = 0;
    for (std::size_t r = line.bar_begin; r < line.bar_end; ++r)
      n += lat.family(out.bar_rows[r].family).ni;
    out.line_store_stride = std::max(out.line_store_stride, n);
  }
  if (coded && kTrimRows) {
    out.bar_row_at = std::move(row_at);
    compact_rows(out, lat);
  } else {
    out.state_count = static_cast<std::size_t>(lat.num_bars());
    out.state_origin.resize(out.bar_rows.size());
    for (std::size_t r = 0; r < out.bar_rows.size(); ++r) {
      const BarRow& row = out.bar_rows[r];
      out.state_origin[r] = lat.bar(static_cast<Family>(row.family), 0, row.j, row.k);
    }
    if (coded)
      out.code_origin = out.state_origin;
    out.row_origin.resize(out.node_rows.size());
    for (std::size_t r = 0; r < out.node_rows.size(); ++r) {
      const NodeRow& row = out.node_rows[r];
      out.row_origin[r] =
          row.centre ? out.slots.centre(lat, row.j, row.k) : out.slots.corner(lat, row.j, row.k);
    }
  }
  return out;
}

} // namespace ldem
