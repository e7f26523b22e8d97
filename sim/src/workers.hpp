// A fixed set of worker threads for the step (private header). The step hands every thread the
// same job and waits for all of them: two barriers per explicit step, no allocation, no locks
// (atomics; workers spin briefly, then yield, so a busy haptic or render thread is not starved).
#pragma once

#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace softatlas::sim {

class WorkerPool {
 public:
  using Job = void (*)(void* context, int thread_index);

  explicit WorkerPool(int threads) : count_(threads) {
    for (int t = 1; t < threads; ++t) workers_.emplace_back([this, t] { loop(t); });
  }
  ~WorkerPool() {
    stop_.store(true, std::memory_order_release);
    epoch_.fetch_add(1, std::memory_order_acq_rel);
    for (std::thread& w : workers_) w.join();
  }
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return count_; }

  // Runs job(context, t) for t = 0..threads-1; t = 0 on the calling thread. Returns when all are
  // done.
  void run(Job job, void* context) {
    job_ = job;
    context_ = context;
    pending_.store(count_ - 1, std::memory_order_release);
    epoch_.fetch_add(1, std::memory_order_acq_rel);
    job(context, 0);
    for (int spin = 0; pending_.load(std::memory_order_acquire) != 0; ++spin)
      if (spin > 4000) std::this_thread::yield();
  }

  // Organs assigned to each thread (balanced by work at make_work()).
  std::vector<std::vector<int32_t>> organs;
  // Connected components (Model::component_begin) assigned to each thread for implicit solves.
  std::vector<std::vector<int32_t>> components;

 private:
  void loop(int t) {
    uint64_t seen = 0;
    while (true) {
      uint64_t e;
      for (int spin = 0; (e = epoch_.load(std::memory_order_acquire)) == seen; ++spin)
        if (spin > 4000) std::this_thread::yield();
      seen = e;
      if (stop_.load(std::memory_order_acquire)) return;
      job_(context_, t);
      pending_.fetch_sub(1, std::memory_order_acq_rel);
    }
  }

  int count_;
  std::vector<std::thread> workers_;
  std::atomic<uint64_t> epoch_{0};
  std::atomic<int> pending_{0};
  std::atomic<bool> stop_{false};
  Job job_ = nullptr;
  void* context_ = nullptr;
};

}  // namespace softatlas::sim
