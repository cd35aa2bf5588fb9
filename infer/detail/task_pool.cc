#include "infer/detail/task_pool.h"

#include <exception>
#include <memory>

#include "common/error.h"

namespace lmb::detail {

// One run(): its tasks' outcomes and how many are still to finish.
struct TaskPool::Batch {
  std::mutex mutex;
  std::condition_variable done;
  size_t remaining = 0;
  std::vector<std::exception_ptr> failures;
};

TaskPool::TaskPool(int threads) {
  LMB_CHECK(threads >= 1 && threads <= 256, "task pool: threads = " << threads << " must be in 1..256");
  for (int t = 1; t < threads; ++t) workers_.emplace_back([this] { work(); });
}

TaskPool::~TaskPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (std::thread& w : workers_) w.join();
}

void TaskPool::work() {
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, nothing left
      task = std::move(queue_.front());
      queue_.pop_front();
    }
    task();
  }
}

void TaskPool::run(const std::vector<std::function<void()>>& tasks) {
  if (tasks.empty()) return;
  auto batch = std::make_shared<Batch>();
  batch->remaining = tasks.size();
  batch->failures.resize(tasks.size());
  const auto wrap = [batch, &tasks](size_t i) {
    try {
      tasks[i]();
    } catch (...) {
      batch->failures[i] = std::current_exception();
    }
    std::lock_guard<std::mutex> lock(batch->mutex);
    if (--batch->remaining == 0) batch->done.notify_all();
  };
  // The workers take tasks 1..n-1 from the queue; the caller runs task 0, then helps with the rest.
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (size_t i = 1; i < tasks.size(); ++i) queue_.emplace_back([wrap, i] { wrap(i); });
  }
  wake_.notify_all();
  wrap(0);
  for (;;) {
    std::function<void()> task;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (queue_.empty()) break;
      task = std::move(queue_.front());
      queue_.pop_front();
    }
    task();
  }
  {
    std::unique_lock<std::mutex> lock(batch->mutex);
    batch->done.wait(lock, [&] { return batch->remaining == 0; });
  }
  for (const std::exception_ptr& f : batch->failures) {
    if (f) std::rethrow_exception(f);
  }
}

}  // namespace lmb::detail
