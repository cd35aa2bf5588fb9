// The MPI seam of distributed training: the learner's Collectives (train/boost/collectives.h) over
// an MPI_Comm, plus what the training job needs besides (string broadcast, barrier, abort). It
// counts the payload bytes it moves and degrades to a one-rank no-op when MPI is not running. Only
// lmb_dist links MPI; the learners (train/boost, train/dist/feature_parallel_learner.h) never see it.
//
// Threading: one thread per rank calls these (MPI_THREAD_SINGLE).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <mpi.h>

#include "train/boost/collectives.h"

namespace lmb {

// MPI for one `lboost` command: initialized only when a launcher started this process (mpirun /
// mpiexec set OMPI_COMM_WORLD_SIZE, srun --mpi=pmix sets PMIX_RANK), so a plain `lboost train` is
// one process without MPI at all. Throws lmb::Error when srun started several tasks without a PMI
// (each would train alone): launch with `srun --mpi=pmix`.
class MpiSession {
 public:
  MpiSession();
  ~MpiSession();  // MPI_Finalize if this session initialized MPI
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  bool active() const { return active_; }
  // True when the environment says an MPI launcher started this process.
  static bool launched_by_mpi();

 private:
  bool active_ = false;
};

class Communicator : public Collectives {
 public:
  // One rank, no MPI (a serial run or a test's reference).
  Communicator() = default;
  // Over an existing communicator (MPI_COMM_WORLD, or a split of it in tests). MPI must be up.
  explicit Communicator(MPI_Comm comm);
  // MPI_COMM_WORLD when `session` is active, else one rank.
  static Communicator world(const MpiSession& session);

  int rank() const override { return rank_; }
  int size() const override { return size_; }

  // Every rank's bytes, concatenated in rank order; offsets (size() + 1) delimit them.
  std::vector<uint8_t> allgather_bytes(const std::vector<uint8_t>& local, std::vector<int64_t>* offsets) override;
  // Root's `data` to every rank (resized on the receivers).
  void broadcast_bytes(std::vector<uint8_t>* data, int root) override;
  void broadcast_string(std::string* text, int root);
  // Every rank's bytes to `root`, which hands them to `take(rank, bytes)` in rank order (one rank's
  // bytes in memory at a time); `take` is not called on the other ranks. Any size (sent in chunks
  // below MPI's int count).
  void gather_bytes(const uint8_t* local, int64_t size, int root,
                    const std::function<void(int, const uint8_t*, int64_t)>& take) override;
  // Point to point: blocking, any size, matched by `tag` (>= 0). Deadlock-free when every rank
  // walks the same list of transfers in the same order.
  void send_bytes(const uint8_t* data, int64_t size, int dest, int tag) override;
  std::vector<uint8_t> recv_bytes(int source, int tag) override;
  int64_t allreduce_max(int64_t local) override;
  int64_t allreduce_sum(int64_t local) override;
  void barrier();
  // Ends every rank of the job (MPI_Abort) with `code`; returns only when not distributed.
  void abort(int code);

  // Payload bytes this rank sent and received through the calls above, since construction
  // (logical: what each other rank must get from it, independent of MPI's collective algorithm).
  int64_t bytes_sent() const { return bytes_sent_; }
  int64_t bytes_received() const { return bytes_received_; }

 private:
  int64_t allreduce(int64_t local, MPI_Op op);
  MPI_Comm comm_ = MPI_COMM_NULL;
  int rank_ = 0;
  int size_ = 1;
  int64_t bytes_sent_ = 0;
  int64_t bytes_received_ = 0;
};

}  // namespace lmb
