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
// Large payloads go in chunks below MPI's int count.
constexpr int64_t kChunk = int64_t{1} << 30;

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

std::vector<uint8_t> Communicator::allgather_bytes(const std::vector<uint8_t>& local, std::vector<int64_t>* offsets) {
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

void Communicator::send_bytes(const uint8_t* data, int64_t size, int dest, int tag) {
  LMB_CHECK(dest >= 0 && dest < size_ && dest != rank_ && tag >= 0 && size >= 0,
            "send_bytes: rank " << rank_ << " to " << dest << " tag " << tag);
  int64_t n = size;
  MPI_Send(&n, 1, MPI_INT64_T, dest, tag, comm_);
  for (int64_t at = 0; at < n; at += kChunk) {
    MPI_Send(data + at, static_cast<int>(std::min(kChunk, n - at)), MPI_BYTE, dest, tag, comm_);
  }
  bytes_sent_ += n + 8;
}

std::vector<uint8_t> Communicator::recv_bytes(int source, int tag) {
  LMB_CHECK(source >= 0 && source < size_ && source != rank_ && tag >= 0,
            "recv_bytes: rank " << rank_ << " from " << source << " tag " << tag);
  int64_t n = 0;
  MPI_Recv(&n, 1, MPI_INT64_T, source, tag, comm_, MPI_STATUS_IGNORE);
  LMB_CHECK(n >= 0, "recv_bytes: rank " << source << " announced " << n << " bytes");
  std::vector<uint8_t> data(static_cast<size_t>(n));
  for (int64_t at = 0; at < n; at += kChunk) {
    MPI_Recv(data.data() + at, static_cast<int>(std::min(kChunk, n - at)), MPI_BYTE, source, tag, comm_,
             MPI_STATUS_IGNORE);
  }
  bytes_received_ += n + 8;
  return data;
}

void Communicator::gather_bytes(const uint8_t* local, int64_t size, int root,
                                const std::function<void(int, const uint8_t*, int64_t)>& take) {
  LMB_CHECK(root >= 0 && root < size_, "gather_bytes: root " << root << " of " << size_);
  if (rank_ != root) {
    send_bytes(local, size, root, 0);
    return;
  }
  for (int r = 0; r < size_; ++r) {
    if (r == rank_) {
      take(r, local, size);
    } else {
      const std::vector<uint8_t> bytes = recv_bytes(r, 0);
      take(r, bytes.data(), static_cast<int64_t>(bytes.size()));
    }
  }
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
