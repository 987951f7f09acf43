#include "parallel/comm.hpp"

#include "energy/exact_sum.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fmt/format.h>

#ifdef LDEM_HAVE_MPI
#include <mpi.h>
#endif

namespace ldem {

#ifdef LDEM_HAVE_MPI

namespace {
// MPI is started only under a launcher (mpirun, srun): started alone, ldem is one process
// and does not pay for MPI's start-up (Open MPI would spawn a daemon for a lone process).
bool g_active = false;

bool under_launcher() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    if (std::getenv(v))
      return true;
  return false;
}
} // namespace

ProcessGroup::ProcessGroup(int& argc, char**& argv) {
  if (!under_launcher())
    return;
  int provided = 0;
  // Only the main thread calls MPI; OpenMP threads work between the calls.
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  g_active = true;
  if (process_rank() != 0 && !std::freopen("/dev/null", "w", stdout))
    std::perror("ldem: stdout of rank > 0");
}

ProcessGroup::~ProcessGroup() {
  if (g_active)
    MPI_Finalize();
}

int process_rank() {
  int r = 0;
  if (g_active)
    MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

int process_count() {
  int n = 1;
  if (g_active)
    MPI_Comm_size(MPI_COMM_WORLD, &n);
  return n;
}

bool built_with_mpi() {
  return true;
}

namespace {
// The two-phase exchange of a subdomain's ghost nodes: pack(axis, dir, out) fills the values to
// send towards dir, unpack(axis, dir, in) takes those received from there.
template <class Pack, class Unpack>
void exchange(const SubdomainRun& run, std::vector<double> (&buf)[4], Pack&& pack,
              Unpack&& unpack) {
  const Subdomain& sub = run.subdomain();
  // Along y first (the owned planes' rows), then along z (whole window planes, with the ghost
  // rows just received): the diagonal neighbours' nodes come through the second phase.
  for (int axis : {1, 2}) {
    MPI_Request req[4];
    int n = 0;
    // buf[0], buf[1]: received from below, above; buf[2], buf[3]: sent below, above.
    for (int side = 0; side < 2; ++side) {
      const int dir = side == 0 ? -1 : +1;
      const std::size_t size = run.halo_size(axis, dir);
      if (size == 0)
        continue;
      const int other = sub.neighbour(axis, dir);
      buf[side].resize(size);
      MPI_Irecv(buf[side].data(), static_cast<int>(size), MPI_DOUBLE, other, axis, MPI_COMM_WORLD,
                &req[n++]);
      pack(axis, dir, buf[2 + side]);
      MPI_Isend(buf[2 + side].data(), static_cast<int>(size), MPI_DOUBLE, other, axis,
                MPI_COMM_WORLD, &req[n++]);
    }
    MPI_Waitall(n, req, MPI_STATUSES_IGNORE);
    for (int side = 0; side < 2; ++side)
      if (run.halo_size(axis, side == 0 ? -1 : +1) > 0)
        unpack(axis, side == 0 ? -1 : +1, buf[side]);
  }
}
} // namespace

void exchange_halos(SubdomainRun& run, std::vector<double> (&buf)[4]) {
  if (!g_active)
    return;
  exchange(
      run, buf, [&](int axis, int dir, std::vector<double>& out) { run.pack(axis, dir, out); },
      [&](int axis, int dir, const std::vector<double>& in) { run.unpack(axis, dir, in); });
}

void exchange_halos(const SubdomainRun& run, std::vector<double>& values,
                    std::vector<double> (&buf)[4]) {
  if (!g_active)
    return;
  exchange(
      run, buf,
      [&](int axis, int dir, std::vector<double>& out) { run.pack(axis, dir, values, out); },
      [&](int axis, int dir, const std::vector<double>& in) { run.unpack(axis, dir, in, values); });
}

void sum_over_processes(ExactSum& sum) {
  if (!g_active)
    return;
  double mine[ExactSum::kDoubles];
  sum.write(mine);
  std::vector<double> all(static_cast<std::size_t>(process_count()) * ExactSum::kDoubles);
  MPI_Allgather(mine, ExactSum::kDoubles, MPI_DOUBLE, all.data(), ExactSum::kDoubles, MPI_DOUBLE,
                MPI_COMM_WORLD);
  sum = ExactSum{}; // every process adds the same parts: exact sums do not depend on the order
  for (std::size_t r = 0; r < all.size(); r += ExactSum::kDoubles) {
    ExactSum part;
    part.read(all.data() + r);
    sum.add(part);
  }
}

void gather_on_first(const std::vector<double>& mine, std::vector<double>& all) {
  if (!g_active) {
    all.assign(mine.begin(), mine.end());
    return;
  }
  const int count = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<std::size_t>(process_count())), offsets(counts.size());
  MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  int total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    offsets[r] = total;
    total += counts[r];
  }
  all.resize(process_rank() == 0 ? static_cast<std::size_t>(total) : 0);
  MPI_Gatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), offsets.data(), MPI_DOUBLE,
              0, MPI_COMM_WORLD);
}

std::vector<double> gather_on_first(const std::vector<double>& mine) {
  std::vector<double> all;
  gather_on_first(mine, all);
  return all;
}

void broadcast_from_first(double* values, int count) {
  if (g_active)
    MPI_Bcast(values, count, MPI_DOUBLE, 0, MPI_COMM_WORLD);
}

std::vector<double> scatter_from_first(const std::vector<std::vector<double>>& parts) {
  if (!g_active)
    return parts.empty() ? std::vector<double>{} : parts[0];
  const bool first = process_rank() == 0;
  std::vector<int> counts(static_cast<std::size_t>(process_count()), 0), offsets(counts.size(), 0);
  std::vector<double> all;
  if (first) {
    if (parts.size() != counts.size())
      throw InputError("scatter: one part per process expected");
    for (std::size_t r = 0; r < parts.size(); ++r) {
      counts[r] = static_cast<int>(parts[r].size());
      offsets[r] = static_cast<int>(all.size());
      all.insert(all.end(), parts[r].begin(), parts[r].end());
    }
  }
  int count = 0;
  MPI_Scatter(counts.data(), 1, MPI_INT, &count, 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::vector<double> mine(static_cast<std::size_t>(count));
  MPI_Scatterv(all.data(), counts.data(), offsets.data(), MPI_DOUBLE, mine.data(), count,
               MPI_DOUBLE, 0, MPI_COMM_WORLD);
  return mine;
}

void broadcast_from_first(std::string& bytes) {
  if (!g_active)
    return;
  auto size = static_cast<long long>(bytes.size());
  MPI_Bcast(&size, 1, MPI_LONG_LONG, 0, MPI_COMM_WORLD);
  bytes.resize(static_cast<std::size_t>(size));
  MPI_Bcast(bytes.data(), static_cast<int>(size), MPI_CHAR, 0, MPI_COMM_WORLD);
}

std::vector<std::string> exchange_bytes(const std::vector<std::string>& parts) {
  if (!g_active)
    return parts;
  const auto ranks = static_cast<std::size_t>(process_count());
  if (parts.size() != ranks)
    throw InputError("exchange_bytes: one part per process expected");
  std::vector<std::uint64_t> out_sizes(ranks), in_sizes(ranks);
  for (std::size_t r = 0; r < ranks; ++r)
    out_sizes[r] = parts[r].size();
  MPI_Alltoall(out_sizes.data(), 1, MPI_UINT64_T, in_sizes.data(), 1, MPI_UINT64_T,
               MPI_COMM_WORLD);
  std::vector<std::string> got(ranks);
  std::vector<MPI_Request> requests;
  constexpr std::uint64_t kPiece = std::uint64_t{1} << 30; // MPI counts are ints
  // (The pieces of one pair go in order under tags 0, 1, ...)
  for (std::size_t r = 0; r < ranks; ++r) {
    got[r].resize(in_sizes[r]);
    for (std::uint64_t at = 0, tag = 0; at < in_sizes[r]; at += kPiece, ++tag)
      MPI_Irecv(got[r].data() + at, static_cast<int>(std::min(kPiece, in_sizes[r] - at)),
                MPI_BYTE, static_cast<int>(r), static_cast<int>(tag), MPI_COMM_WORLD,
                &requests.emplace_back());
  }
  for (std::size_t r = 0; r < ranks; ++r)
    for (std::uint64_t at = 0, tag = 0; at < out_sizes[r]; at += kPiece, ++tag)
      MPI_Isend(parts[r].data() + at, static_cast<int>(std::min(kPiece, out_sizes[r] - at)),
                MPI_BYTE, static_cast<int>(r), static_cast<int>(tag), MPI_COMM_WORLD,
                &requests.emplace_back());
  MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE);
  return got;
}

std::vector<std::uint64_t> gather_on_all(const std::vector<std::uint64_t>& mine) {
  if (!g_active)
    return mine;
  const int count = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<std::size_t>(process_count())), offsets(counts.size());
  MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  int total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    offsets[r] = total;
    total += counts[r];
  }
  std::vector<std::uint64_t> all(static_cast<std::size_t>(total));
  MPI_Allgatherv(mine.data(), count, MPI_UINT64_T, all.data(), counts.data(), offsets.data(),
                 MPI_UINT64_T, MPI_COMM_WORLD);
  return all;
}

void abort_processes(int code) {
  if (g_active && process_count() > 1) {
    std::fflush(stdout);
    std::fflush(stderr);
    MPI_Abort(MPI_COMM_WORLD, code);
  }
}

namespace {
double reduce(double x, MPI_Op op) {
  double y = x;
  if (g_active)
    MPI_Allreduce(&x, &y, 1, MPI_DOUBLE, op, MPI_COMM_WORLD);
  return y;
}
} // namespace

double min_over_processes(double x) {
  return reduce(x, MPI_MIN);
}

double max_over_processes(double x) {
  return reduce(x, MPI_MAX);
}

double sum_over_processes(double x) {
  return reduce(x, MPI_SUM);
}

std::uint64_t wrapping_sum_over_processes(std::uint64_t x) {
  std::uint64_t y = x;
  if (g_active)
    MPI_Allreduce(&x, &y, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  return y;
}

void barrier() {
  if (g_active)
    MPI_Barrier(MPI_COMM_WORLD);
}

#else

ProcessGroup::ProcessGroup(int&, char**&) {}
ProcessGroup::~ProcessGroup() = default;
int process_rank() {
  return 0;
}
int process_count() {
  return 1;
}
bool built_with_mpi() {
  return false;
}
void exchange_halos(SubdomainRun& run, std::vector<double> (&)[4]) {
  if (run.subdomain().ranks > 1)
    throw InputError("a subdomain of several ranks needs a build with MPI");
}
void exchange_halos(const SubdomainRun& run, std::vector<double>&, std::vector<double> (&)[4]) {
  if (run.subdomain().ranks > 1)
    throw InputError("a subdomain of several ranks needs a build with MPI");
}
void sum_over_processes(ExactSum&) {}
std::vector<double> gather_on_first(const std::vector<double>& mine) {
  return mine;
}
void gather_on_first(const std::vector<double>& mine, std::vector<double>& all) {
  all.assign(mine.begin(), mine.end());
}
void broadcast_from_first(double*, int) {}
std::vector<double> scatter_from_first(const std::vector<std::vector<double>>& parts) {
  return parts.empty() ? std::vector<double>{} : parts[0];
}
void broadcast_from_first(std::string&) {}
std::vector<std::string> exchange_bytes(const std::vector<std::string>& parts) {
  return parts;
}
std::vector<std::uint64_t> gather_on_all(const std::vector<std::uint64_t>& mine) {
  return mine;
}
void abort_processes(int) {}
double min_over_processes(double x) {
  return x;
}
double max_over_processes(double x) {
  return x;
}
double sum_over_processes(double x) {
  return x;
}
std::uint64_t wrapping_sum_over_processes(std::uint64_t x) {
  return x;
}
void barrier() {}

#endif

// A SharedFile is written through MPI-IO by a run of several processes, and through stdio by
// one (also in a build with MPI, started without mpirun).
SharedFile::SharedFile(const std::string& path) : path_(path), part_(path + ".part") {
#ifdef LDEM_HAVE_MPI
  if (g_active) {
    MPI_File fh = MPI_FILE_NULL;
    if (MPI_File_open(MPI_COMM_WORLD, part_.c_str(), MPI_MODE_CREATE | MPI_MODE_WRONLY,
                      MPI_INFO_NULL, &fh) != MPI_SUCCESS)
      throw InputError(fmt::format("{}: cannot write", part_));
    MPI_File_set_size(fh, 0); // a stale part of an earlier run goes
    handle_ = new MPI_File(fh);
    mpi_ = true;
    return;
  }
#endif
  std::FILE* f = std::fopen(part_.c_str(), "wb");
  if (!f)
    throw InputError(fmt::format("{}: cannot write ({})", part_, std::strerror(errno)));
  handle_ = f;
}

SharedFile::~SharedFile() {
  // Dropped before commit() (an error while it was written): not a file of the run.
  if (!handle_)
    return;
  close();
  if (!mpi_ || process_rank() == 0)
    std::remove(part_.c_str());
}

bool SharedFile::close() {
  if (!handle_)
    return true;
  bool ok = true;
#ifdef LDEM_HAVE_MPI
  if (mpi_) {
    ok = MPI_File_close(static_cast<MPI_File*>(handle_)) == MPI_SUCCESS;
    delete static_cast<MPI_File*>(handle_);
    handle_ = nullptr;
    return ok;
  }
#endif
  ok = std::fclose(static_cast<std::FILE*>(handle_)) == 0; // (a full disk shows here)
  handle_ = nullptr;
  return ok;
}

void SharedFile::write_at(std::uint64_t position, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const char*>(data);
#ifdef LDEM_HAVE_MPI
  if (mpi_) {
    while (bytes > 0) { // MPI counts are ints: pieces of at most 1 GiB
      const std::size_t n = std::min<std::size_t>(bytes, std::size_t{1} << 30);
      if (MPI_File_write_at(*static_cast<MPI_File*>(handle_), static_cast<MPI_Offset>(position), p,
                            static_cast<int>(n), MPI_BYTE, MPI_STATUS_IGNORE) != MPI_SUCCESS)
        throw InputError(fmt::format("{}: write failed", part_));
      p += n;
      position += n;
      bytes -= n;
    }
    return;
  }
#endif
  auto* f = static_cast<std::FILE*>(handle_);
  if (fseeko(f, static_cast<off_t>(position), SEEK_SET) != 0 ||
      std::fwrite(p, 1, bytes, f) != bytes)
    throw InputError(fmt::format("{}: write failed ({})", part_, std::strerror(errno)));
}

void SharedFile::commit() {
  if (!handle_)
    return;
  const bool was_mpi = mpi_;
  if (!close()) {
    const int err = errno;
    if (!was_mpi || process_rank() == 0)
      std::remove(part_.c_str()); // never renamed: the file before it, if any, stays
    throw InputError(was_mpi ? fmt::format("{}: write failed; not written", path_)
                             : fmt::format("{}: write failed ({}); not written", path_,
                                           std::strerror(err)));
  }
  if ((!was_mpi || process_rank() == 0) && std::rename(part_.c_str(), path_.c_str()) != 0)
    throw InputError(
        fmt::format("{}: cannot rename to {} ({})", part_, path_, std::strerror(errno)));
}

StableStep distributed_stable_step(SubdomainRun& run, const Lattice& whole) {
  const Simulation& sim = run.sim();
  const Lattice& local = sim.lattice();
  StableStepParts parts;
  parts.owned.resize(local.num_nodes());
  parts.global_node.resize(local.num_nodes());
  for (index_t n = 0; n < local.num_nodes(); ++n) {
    parts.owned[n] = run.owns(n);
    const NodeAddress a = run.global_address(n);
    parts.global_node[n] = a.centre ? whole.centre(a.i, a.j, a.k) : whole.corner(a.i, a.j, a.k);
  }
  std::vector<double> buffers[4];
  parts.exchange = [&](std::vector<double>& values) { exchange_halos(run, values, buffers); };
  parts.sum = [](ExactSum& sum) { sum_over_processes(sum); };
  parts.max = [](double x) { return max_over_processes(x); };
  return compute_stable_step(local, sim.table(), sim.masses(), sim.held_dofs(), &parts);
}

EnergySums gather_energies(const SubdomainRun& run) {
  EnergyRows rows;
  run.append_owned_energy_rows(rows);
  const std::vector<double> bar_keys = gather_on_first(rows.bar_keys);
  const std::vector<std::size_t> bar_order = key_order(bar_keys);
  ExactSum kinetic;
  for (double x : gather_on_first(rows.kinetic))
    kinetic.add(x);
  double sums[3] = {sum_in_order(gather_on_first(rows.elastic), bar_order),
                    sum_in_order(gather_on_first(rows.damage), bar_order), kinetic.value()};
  broadcast_from_first(sums, 3);
  return {sums[0], sums[1], sums[2]};
}

} // namespace ldem
