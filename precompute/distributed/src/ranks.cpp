#include "phasecast/precompute/distributed/ranks.h"

#include <fmt/format.h>

#ifdef PHASECAST_HAVE_MPI
#include <mpi.h>
#endif

#include <climits>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace phasecast::precompute {

bool started_by_mpi_launcher() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"}) {
    if (std::getenv(name)) return true;
  }
  return false;
}

void check_not_unwired_slurm_task() {
  const char* tasks = std::getenv("SLURM_STEP_NUM_TASKS");
  if (!tasks || std::atoi(tasks) <= 1 || started_by_mpi_launcher()) return;
  throw std::runtime_error(fmt::format(
      "one of {} tasks of a Slurm step, but no MPI launcher connected them (no PMI/PMIx variables): each "
      "would run the whole job; start it with srun --mpi=pmix or mpirun (docs/distributed.md)",
      tasks));
}

Ranks& Ranks::world() {
  static Ranks w;
  return w;
}

void Ranks::require_one_process(const std::string& command) const {
  if (distributed()) {
    throw std::runtime_error(fmt::format(
        "{} runs in one process: start it without mpirun (sample, reduce and run spread over ranks)",
        command));
  }
}

#ifdef PHASECAST_HAVE_MPI

Ranks::Ranks() {
  check_not_unwired_slurm_task();
  if (!started_by_mpi_launcher()) return;
  int ready = 0;
  MPI_Initialized(&ready);
  if (!ready) MPI_Init(nullptr, nullptr);
  initialised_ = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

Ranks::~Ranks() {
  if (initialised_) MPI_Finalize();
}

void Ranks::barrier() const {
  if (initialised_) MPI_Barrier(MPI_COMM_WORLD);
}

void Ranks::share_rows(MatrixXfR& rows) const {
  if (!distributed()) return;
  if (rows.cols() > INT_MAX) throw std::runtime_error("share_rows: a row of more than 2^31 floats");
  for (Eigen::Index j = 0; j < rows.rows(); ++j) {
    MPI_Bcast(rows.row(j).data(), static_cast<int>(rows.cols()), MPI_FLOAT, static_cast<int>(j % size_),
              MPI_COMM_WORLD);
  }
}

void Ranks::sum(std::vector<long long>& values) const {
  if (distributed())
    MPI_Allreduce(MPI_IN_PLACE, values.data(), static_cast<int>(values.size()), MPI_LONG_LONG, MPI_SUM,
                  MPI_COMM_WORLD);
}

long long Ranks::max(long long value) const {
  if (distributed()) MPI_Allreduce(MPI_IN_PLACE, &value, 1, MPI_LONG_LONG, MPI_MAX, MPI_COMM_WORLD);
  return value;
}

double Ranks::min(double value) const {
  if (distributed()) MPI_Allreduce(MPI_IN_PLACE, &value, 1, MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD);
  return value;
}

void Ranks::abort_all(int code) const {
  std::fflush(stdout);
  std::fflush(stderr);
  if (distributed()) MPI_Abort(MPI_COMM_WORLD, code);
}

#else

Ranks::Ranks() {
  check_not_unwired_slurm_task();
  if (started_by_mpi_launcher()) {
    throw std::runtime_error(
        "started by an MPI launcher, but this phasecast-precompute was built without MPI (install "
        "libopenmpi-dev, reconfigure and rebuild; docs/distributed.md)");
  }
}

Ranks::~Ranks() = default;
void Ranks::barrier() const {}
void Ranks::share_rows(MatrixXfR&) const {}
void Ranks::sum(std::vector<long long>&) const {}
long long Ranks::max(long long value) const {
  return value;
}
double Ranks::min(double value) const {
  return value;
}
void Ranks::abort_all(int) const {}

#endif

}  // namespace phasecast::precompute
