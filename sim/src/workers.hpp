// A fixed set of worker threads for the step (private header). The step hands every thread the
// same job and waits for all of them: two barriers per explicit step, no allocation, no locks
// (atomics; workers spin briefly, then yield, so a busy haptic or render thread is not starved).
#pragma once

#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

#if (defined(__x86_64__) || defined(__i386__)) && defined(__SSE__) && !defined(__EMSCRIPTEN__)
#include <xmmintrin.h>
#define SOFTATLAS_SIM_MXCSR 1
#endif

namespace softatlas::sim {

// Float denormals flushed to zero (FTZ) and read as zero (DAZ) while the physics runs, on the
// thread that steps and on the worker threads. Near convergence the float CG's residual is
// concentrated where the load is; elsewhere its entries are tiny and their squares (r . z) fall
// below float's 1.2e-38, where x86 takes a microcode assist of about 100 cycles per operation:
// perf put 84 % of cg_update on one vfmadd231ps and the implicit step cost 19.5x a bench-ref
// TMSM step (docs/performance.md). Values that small are far below the CG's float floor
// (1e-7 relative), so flushing them changes nothing the solve can resolve. The caller's mode is
// restored when the scope ends. Other targets (wasm, ARM) keep their default mode.
class FlushDenormals {
 public:
  FlushDenormals() {
#ifdef SOFTATLAS_SIM_MXCSR
    saved_ = _mm_getcsr();
    _mm_setcsr(saved_ | kFtzDaz);
#endif
  }
  ~FlushDenormals() {
#ifdef SOFTATLAS_SIM_MXCSR
    _mm_setcsr(saved_);
#endif
  }
  FlushDenormals(const FlushDenormals&) = delete;
  FlushDenormals& operator=(const FlushDenormals&) = delete;

 private:
#ifdef SOFTATLAS_SIM_MXCSR
  static constexpr unsigned kFtzDaz = 0x8040;  // MXCSR bit 15 FTZ, bit 6 DAZ
  unsigned saved_ = 0;
#endif
};

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
    const FlushDenormals flush;  // a worker only ever runs physics jobs
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
