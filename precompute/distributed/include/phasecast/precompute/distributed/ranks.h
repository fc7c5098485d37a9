#pragma once
// This process's place among the processes of one precompute run
// (docs/distributed.md): MPI's world when a launcher (mpirun, srun) started
// it, a world of one otherwise. MPI is initialised only under a launcher, so
// the plain command runs exactly as without MPI.
//
// Work is dealt out by index, item k to rank k mod N: fixed, so a result never
// depends on timing, and a resumed run gives every rank the same items. Each
// rank's items are computed alone and then shared, bit for bit, so the result
// is the same for any N.

#include "phasecast/core/eigen_types.h"

#include <string>
#include <vector>

namespace phasecast::precompute {

class Ranks {
 public:
  // The run's world; the first call initialises MPI when a launcher started
  // this process. Throws std::runtime_error when one did but this build has
  // no MPI (each process would otherwise do the whole run on its own).
  static Ranks& world();
  ~Ranks();
  Ranks(const Ranks&) = delete;
  Ranks& operator=(const Ranks&) = delete;

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool distributed() const { return size_ > 1; }
  bool owns(int item) const { return item % size_ == rank_; }

  // Waits for every rank (a rank that failed has ended the run: abort_all).
  void barrier() const;
  // Row j of `rows` (all ranks: same shape) from the rank that owns j, to every rank.
  void share_rows(MatrixXfR& rows) const;
  // Over every rank, for every rank: element-wise sums, the largest, the smallest.
  void sum(std::vector<long long>& values) const;
  long long max(long long value) const;
  double min(double value) const;
  // Throws std::runtime_error naming `command` in a world of more than one
  // (only sample, reduce and run share their work; the others would each do all of it).
  void require_one_process(const std::string& command) const;
  // Ends every process of the run with `code` (MPI_Abort) once this one has
  // printed why; returns only in a world of one.
  void abort_all(int code) const;

 private:
  Ranks();
  int rank_ = 0;
  int size_ = 1;
  bool initialised_ = false;
};

// Whether a launcher started this process (Open MPI, MPICH/PMI, PMIx/Slurm).
bool started_by_mpi_launcher();

// Throws std::runtime_error when this process is one of several tasks of a
// Slurm step that no MPI launcher wired together (srun without --mpi=pmix on
// a site whose default is none): each task would run the whole job into the
// same work folder.
void check_not_unwired_slurm_task();

}  // namespace phasecast::precompute
