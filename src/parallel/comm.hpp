// The processes of a run. Built with MPI (LDEM_HAVE_MPI) and started by mpirun, a run spans
// the world's ranks; otherwise, and under a plain start, it is one process and every
// function here is the identity.
#pragma once

#include "parallel/subdomain.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace ldem {

class ExactSum;

// Initialises MPI for the life of main (when built with it); ranks beyond the first send
// their standard output nowhere, so that a run prints once.
class ProcessGroup {
public:
  ProcessGroup(int& argc, char**& argv);
  ~ProcessGroup();
  ProcessGroup(const ProcessGroup&) = delete;
  ProcessGroup& operator=(const ProcessGroup&) = delete;
};

int process_rank();
int process_count();
bool built_with_mpi();

// Exchanges the ghost nodes of a subdomain with its neighbours, along y then along z
// (non-blocking sends and receives, then the unpacking, per axis); `buffers` holds four
// reusable vectors.
void exchange_halos(SubdomainRun& run, std::vector<double> (&buffers)[4]);
// The same for any 3 values per window node (node after node) in `values`.
void exchange_halos(const SubdomainRun& run, std::vector<double>& values,
                    std::vector<double> (&buffers)[4]);

// The stable time step of the whole body (solver/stable_step.hpp), every process computing on
// its subdomain: bit for bit one process's step of the body. Collective.
StableStep distributed_stable_step(SubdomainRun& run, const Lattice& whole);

// Every process's part added (exactly), on every process.
void sum_over_processes(ExactSum& sum);

// The whole body's elastic, dissipated and kinetic energy of the last report step, from
// every rank's owned rows summed in the body's row order (their keys): the numbers one
// process gives, bit for bit. Every rank gets them.
struct EnergySums {
  double elastic = 0.0, damage = 0.0, kinetic = 0.0;
};
EnergySums gather_energies(const SubdomainRun& run);

// Every rank's `mine`, concatenated in rank order, on rank 0 (empty on the others); and
// rank 0's values to every rank.
std::vector<double> gather_on_first(const std::vector<double>& mine);
// The same into `all`, whose memory is kept from call to call (a fresh vector of megabytes
// costs its page faults at every snapshot).
void gather_on_first(const std::vector<double>& mine, std::vector<double>& all);
void broadcast_from_first(double* values, int count);

// Rank 0's parts[p] to rank p (parts is read on rank 0 only); returns this rank's part.
std::vector<double> scatter_from_first(const std::vector<std::vector<double>>& parts);
// Rank 0's bytes to every rank.
void broadcast_from_first(std::string& bytes);
// parts[r] of every rank to rank r (parts: one per rank); returns what each rank sent to this
// one, by rank. Any sizes (sent in pieces of at most 1 GiB). Collective.
std::vector<std::string> exchange_bytes(const std::vector<std::string>& parts);
// Every rank's values, concatenated in rank order, on every rank. Collective.
std::vector<std::uint64_t> gather_on_all(const std::vector<std::uint64_t>& mine);

// Ends every process of the run with `code` (MPI_Abort): for an error on some processes
// after they stopped agreeing step by step, which would leave the others waiting forever.
// Without MPI, or in one process, it returns and the caller ends as usual.
void abort_processes(int code);

// A file that every process writes parts of, each at its own positions (MPI-IO), under
// "<path>.part", renamed to <path> by the first process once all have closed it: as
// OutputFile, a stop part-way never leaves a half-written file under its final name.
// Opening and commit() are collective; write_at is not. Throws InputError when the file
// cannot be opened or written.
class SharedFile {
public:
  explicit SharedFile(const std::string& path);
  ~SharedFile();
  SharedFile(const SharedFile&) = delete;
  SharedFile& operator=(const SharedFile&) = delete;
  void write_at(std::uint64_t position, const void* data, std::size_t bytes);
  void commit();

private:
  std::string path_, part_;
  bool close();            // false if the last writes failed
  void* handle_ = nullptr; // MPI_File (mpi_), or std::FILE*
  bool mpi_ = false;
};

double min_over_processes(double x);
double max_over_processes(double x);
// The sum (counts, exact below 2^53).
double sum_over_processes(double x);
// The sum modulo 2^64 (checksums that add over the pieces of a file).
std::uint64_t wrapping_sum_over_processes(std::uint64_t x);
void barrier();

} // namespace ldem
