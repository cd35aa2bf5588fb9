// What the learner's parts exchange between the processes (ranks) of a distributed run, as a small
// interface: byte gathers, broadcasts, point-to-point transfers and integer reductions. The serial
// learner runs on one_process() (every call is the identity); the distributed layer implements it
// over MPI (train/dist/communicator.h). The learner never sees MPI.
//
// Every call is collective over the ranks unless it says otherwise; ranks make the same calls in
// the same order.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

namespace lmb {

class Collectives {
 public:
  virtual ~Collectives() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  bool distributed() const { return size() > 1; }

  // Every rank's bytes, concatenated in rank order; offsets (size() + 1) delimit them.
  virtual std::vector<uint8_t> allgather_bytes(const std::vector<uint8_t>& local, std::vector<int64_t>* offsets) = 0;
  // Root's `data` to every rank (resized on the receivers).
  virtual void broadcast_bytes(std::vector<uint8_t>* data, int root) = 0;
  // Every rank's bytes to `root`, which hands them to `take(rank, bytes, size)` in rank order (one
  // rank's bytes in memory at a time); `take` is not called on the other ranks.
  virtual void gather_bytes(const uint8_t* local, int64_t size, int root,
                            const std::function<void(int, const uint8_t*, int64_t)>& take) = 0;
  // Point to point (only the two ranks call): blocking, matched by `tag` (>= 0). Deadlock-free
  // when every rank walks the same list of transfers in the same order.
  virtual void send_bytes(const uint8_t* data, int64_t size, int dest, int tag) = 0;
  virtual std::vector<uint8_t> recv_bytes(int source, int tag) = 0;
  virtual int64_t allreduce_sum(int64_t local) = 0;
  virtual int64_t allreduce_max(int64_t local) = 0;
};

// One process: rank 0 of 1. Point-to-point calls throw lmb::Error (there is no other rank).
Collectives& one_process();

}  // namespace lmb
