#include "train/dist/communicator.h"

#include <cstdlib>
#include <limits>

#include "common/error.h"

namespace lmb {

namespace {
bool env_set(const char* name) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0';
}
int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? std::atoi(v) : fallback;
}
}  // namespace

bool MpiSession::launched_by_mpi() {
  return env_set("OMPI_COMM_WORLD_SIZE") || env_set("PMIX_RANK") || env_set("PMI_RANK");
}

MpiSession::MpiSession() {
  if (!launched_by_mpi()) {
    // srun without --mpi=pmix starts N independent processes: refuse rather than train N times.
    LMB_CHECK(!env_set("SLURM_STEP_ID") || env_int("SLURM_STEP_NUM_TASKS", 1) <= 1,
              "srun started " << env_int("SLURM_STEP_NUM_TASKS", 1)
                              << " tasks without an MPI process manager: launch with `srun --mpi=pmix`");
    return;
  }
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (initialized) return;
  MPI_Init(nullptr, nullptr);
  active_ = true;
}

MpiSession::~MpiSession() {
  if (!active_) return;
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

Communicator::Communicator(MPI_Comm comm) : comm_(comm) {
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
}

Communicator Communicator::world(const MpiSession& session) {
  return session.active() ? Communicator(MPI_COMM_WORLD) : Communicator();
}

std::vector<uint8_t> Communicator::allgather_bytes(const std::vector<uint8_t>& local,
                                                   std::vector<int64_t>* offsets) {
  offsets->assign(static_cast<size_t>(size_) + 1, 0);
  if (size_ == 1) {
    (*offsets)[1] = static_cast<int64_t>(local.size());
    return local;
  }
  LMB_CHECK(local.size() <= static_cast<size_t>(std::numeric_limits<int>::max()),
            "allgather: " << local.size() << " bytes on rank " << rank_ << " exceed MPI's int count");
  const int n = static_cast<int>(local.size());
  std::vector<int> counts(static_cast<size_t>(size_)), displs(static_cast<size_t>(size_));
  MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_);
  int64_t total = 0;
  for (int r = 0; r < size_; ++r) {
    (*offsets)[r] = total;
    total += counts[r];
  }
  (*offsets)[size_] = total;
  LMB_CHECK(total <= std::numeric_limits<int>::max(), "allgather: " << total << " bytes exceed MPI's int count");
  for (int r = 0; r < size_; ++r) displs[r] = static_cast<int>((*offsets)[r]);
  std::vector<uint8_t> all(static_cast<size_t>(total));
  MPI_Allgatherv(local.data(), n, MPI_BYTE, all.data(), counts.data(), displs.data(), MPI_BYTE, comm_);
  bytes_sent_ += static_cast<int64_t>(sizeof(int) + local.size()) * (size_ - 1);
  bytes_received_ += static_cast<int64_t>(sizeof(int)) * (size_ - 1) + total - n;
  return all;
}

void Communicator::broadcast_bytes(std::vector<uint8_t>* data, int root) {
  if (size_ == 1) return;
  int64_t n = static_cast<int64_t>(data->size());
  MPI_Bcast(&n, 1, MPI_INT64_T, root, comm_);
  data->resize(static_cast<size_t>(n));
  // In chunks below MPI's int count.
  constexpr int64_t kChunk = int64_t{1} << 30;
  for (int64_t at = 0; at < n; at += kChunk) {
    MPI_Bcast(data->data() + at, static_cast<int>(std::min(kChunk, n - at)), MPI_BYTE, root, comm_);
  }
  if (rank_ == root) {
    bytes_sent_ += (n + 8) * (size_ - 1);
  } else {
    bytes_received_ += n + 8;
  }
}

void Communicator::broadcast_string(std::string* text, int root) {
  std::vector<uint8_t> bytes(text->begin(), text->end());
  broadcast_bytes(&bytes, root);
  text->assign(bytes.begin(), bytes.end());
}

int64_t Communicator::allreduce(int64_t local, MPI_Op op) {
  if (size_ == 1) return local;
  int64_t out = 0;
  MPI_Allreduce(&local, &out, 1, MPI_INT64_T, op, comm_);
  bytes_sent_ += 8 * (size_ - 1);
  bytes_received_ += 8 * (size_ - 1);
  return out;
}

int64_t Communicator::allreduce_max(int64_t local) { return allreduce(local, MPI_MAX); }
int64_t Communicator::allreduce_sum(int64_t local) { return allreduce(local, MPI_SUM); }

void Communicator::barrier() {
  if (size_ > 1) MPI_Barrier(comm_);
}

void Communicator::abort(int code) {
  if (size_ > 1) MPI_Abort(comm_, code);
}

}  // namespace lmb
