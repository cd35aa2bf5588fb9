// A fixed set of worker threads that run batches of tasks: the caller submits a batch, runs tasks
// of it itself, and returns when every task of the batch has finished. Batches of several callers
// may run at once (each waits for its own). Internal to lmb_infer (not installed).
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace lmb::detail {

class TaskPool {
 public:
  // `threads` - 1 workers (threads >= 1; 1 = the caller runs every task).
  explicit TaskPool(int threads);
  ~TaskPool();
  TaskPool(const TaskPool&) = delete;
  TaskPool& operator=(const TaskPool&) = delete;
  int threads() const { return static_cast<int>(workers_.size()) + 1; }

  // Runs every task once, on the workers and the calling thread, and returns when all have
  // finished. The first exception a task threw (in task order) is rethrown after that.
  void run(const std::vector<std::function<void()>>& tasks);

 private:
  struct Batch;
  void work();

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> queue_;  // guarded by mutex_
  bool stopping_ = false;                    // guarded by mutex_
  std::vector<std::thread> workers_;
};

}  // namespace lmb::detail
