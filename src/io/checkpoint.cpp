#include "io/checkpoint.hpp"

#include <fmt/format.h>
#include <fstream>

namespace ldem::checkpoint {

std::string get_str(const std::string& in, std::size_t& pos) {
  std::uint64_t n = 0;
  get(in, pos, n);
  if (pos + n > in.size())
    throw InputError("checkpoint: truncated");
  std::string s = in.substr(pos, n);
  pos += n;
  return s;
}

std::uint64_t fnv1a(const char* p, std::size_t n, std::uint64_t h) {
  for (std::size_t i = 0; i < n; ++i)
    h = (h ^ static_cast<unsigned char>(p[i])) * 0x100000001b3ull;
  return h;
}

namespace {
std::uint64_t mix(std::uint64_t z) { // splitmix64's finaliser
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
} // namespace

std::uint64_t word_hash(std::uint64_t place, double value) {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &value, sizeof bits);
  return mix(bits ^ mix(place + 0x9E3779B97F4A7C15ull));
}

std::string header_bytes(const std::string& meta, const std::string& progress,
                         std::uint64_t checksum) {
  std::string out(kMagic, 8);
  put(out, kVersion);
  put(out, static_cast<std::uint64_t>(meta.size()));
  put(out, static_cast<std::uint64_t>(progress.size()));
  put(out, checksum);
  return out;
}

Header read_header(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in)
    throw InputError(fmt::format("{}: no checkpoint to resume from", path));
  Header h;
  h.file_bytes = static_cast<std::uint64_t>(in.tellg());
  in.seekg(0);
  std::string head(kHeaderBytes, '\0');
  if (h.file_bytes < kHeaderBytes || !in.read(head.data(), kHeaderBytes) ||
      head.compare(0, 8, std::string(kMagic, 8)) != 0)
    throw InputError(fmt::format("{}: not an ldem checkpoint (or truncated)", path));
  std::size_t p = 8;
  std::uint32_t version = 0;
  std::uint64_t meta = 0, progress = 0;
  get(head, p, version);
  if (version != kVersion)
    throw InputError(fmt::format(
        "{}: checkpoint format version {}, written by {} ldem; this ldem reads version {} only: "
        "run the case again from the start",
        path, version, version < kVersion ? "an older" : "another", kVersion));
  get(head, p, meta);
  get(head, p, progress);
  get(head, p, h.checksum);
  if (h.file_bytes < Header::arrays_offset(meta, progress))
    throw InputError(fmt::format("{}: truncated checkpoint ({} bytes, its header says at least "
                                 "{})",
                                 path, h.file_bytes, Header::arrays_offset(meta, progress)));
  h.meta.resize(meta);
  h.progress.resize(progress);
  if (!in.read(h.meta.data(), static_cast<std::streamsize>(meta)) ||
      !in.read(h.progress.data(), static_cast<std::streamsize>(progress)))
    throw InputError(fmt::format("{}: cannot read the checkpoint", path));
  return h;
}

std::uint64_t Progress::array_place(std::size_t a) const {
  std::uint64_t place = 0;
  for (std::size_t q = 0; q < a; ++q)
    place += arrays[q].per_bar ? bars : nodes;
  return place;
}

std::string progress_bytes(const Progress& p) {
  std::string out;
  put(out, p.step);
  put(out, p.dt);
  double ledger[Ledger::State::kDoubles];
  p.ledger.write(ledger);
  put(out, ledger);
  put(out, p.report);
  put(out, p.nodes);
  put(out, p.bars);
  put_str(out, p.law);
  put(out, static_cast<std::uint64_t>(p.arrays.size()));
  for (const Simulation::NamedArray& a : p.arrays) {
    put_str(out, a.name);
    put(out, static_cast<std::uint8_t>(a.per_bar));
  }
  put(out, static_cast<std::uint64_t>(p.events.size()));
  for (const Event& e : p.events) {
    put(out, e.bar);
    put(out, e.state);
    put(out, e.step);
  }
  put(out, static_cast<std::uint64_t>(p.platens.size()));
  for (double v : p.platens)
    put(out, v);
  return out;
}

Progress read_progress(const Header& h, const std::string& path) {
  const std::string& in = h.progress;
  std::size_t pos = 0;
  Progress p;
  try {
    get(in, pos, p.step);
    get(in, pos, p.dt);
    double ledger[Ledger::State::kDoubles];
    get(in, pos, ledger);
    p.ledger.read(ledger);
    get(in, pos, p.report);
    get(in, pos, p.nodes);
    get(in, pos, p.bars);
    p.law = get_str(in, pos);
    std::uint64_t n = 0;
    get(in, pos, n);
    for (std::uint64_t q = 0; q < n && pos < in.size(); ++q) {
      Simulation::NamedArray a{get_str(in, pos), false};
      std::uint8_t per_bar = 0;
      get(in, pos, per_bar);
      a.per_bar = per_bar != 0;
      p.arrays.push_back(std::move(a));
    }
    get(in, pos, n);
    for (std::uint64_t q = 0; q < n && pos < in.size(); ++q) {
      Event e{};
      get(in, pos, e.bar);
      get(in, pos, e.state);
      get(in, pos, e.step);
      p.events.push_back(e);
    }
    get(in, pos, n);
    for (std::uint64_t q = 0; q < n && pos < in.size(); ++q) {
      double v = 0.0;
      get(in, pos, v);
      p.platens.push_back(v);
    }
  } catch (const InputError&) {
    throw InputError(fmt::format("{}: truncated checkpoint (its progress ends early)", path));
  }
  return p;
}

void check_resumes(const Progress& file, const Header& h, const Progress& body,
                   const std::string& path) {
  if (file.nodes != body.nodes || file.bars != body.bars)
    throw InputError(fmt::format("{}: a checkpoint of a body of {} nodes and {} bars; this case "
                                 "has {} and {}",
                                 path, file.nodes, file.bars, body.nodes, body.bars));
  if (file.dt != body.dt)
    throw InputError(fmt::format("{}: its time step {:.17g} s differs from this case's {:.17g} s",
                                 path, file.dt, body.dt));
  if (file.law != body.law)
    throw InputError(fmt::format("{}: a checkpoint of a run with the bar law \"{}\"; this case "
                                 "uses \"{}\"",
                                 path, file.law, body.law));
  if (file.platens.size() != body.platens.size())
    throw InputError(fmt::format("{}: a checkpoint of a run with {} platens; this case has {}",
                                 path, file.platens.size() / 6, body.platens.size() / 6));
  const auto names = [](const Progress& p) {
    std::string s;
    for (const Simulation::NamedArray& a : p.arrays)
      s += (s.empty() ? "" : ", ") + a.name + (a.per_bar ? " (per bar)" : " (per node)");
    return s;
  };
  bool same = file.arrays.size() == body.arrays.size();
  for (std::size_t a = 0; same && a < file.arrays.size(); ++a)
    same = file.arrays[a].name == body.arrays[a].name &&
           file.arrays[a].per_bar == body.arrays[a].per_bar;
  if (!same)
    throw InputError(
        fmt::format("{}: its arrays are {}; this run's are {}", path, names(file), names(body)));
  const std::uint64_t expected = h.arrays_at() + 8 * body.array_doubles();
  if (h.file_bytes != expected)
    throw InputError(fmt::format("{}: truncated checkpoint ({} bytes, {} expected)", path,
                                 h.file_bytes, expected));
}

} // namespace ldem::checkpoint
