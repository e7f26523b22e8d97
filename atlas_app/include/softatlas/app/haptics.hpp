// Haptics: the Device interface, the scripted and mouse devices, force shaping, and the 1 kHz
// loop thread with its lock-free exchange with the physics thread.
//
//   device --read(t)--> HapticLoop (1 kHz thread) --SeqLock<ToolCommand>--> physics thread
//                       (virtual coupling: proxy)      (attachment at the proxy)
//   device <--write_force-- ForceShaper <-- HapticCoupling <--SeqLock<LocalModel>-- physics
//
// The loop never waits for the physics: every tick it recomputes the force from the last
// published local model of the tissue (virtual_coupling.hpp), so the force changes at 1 kHz
// although the physics may step far slower. It never allocates or locks after start().
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "softatlas/app/tool_command.hpp"
#include "softatlas/app/virtual_coupling.hpp"

namespace softatlas::app {

class Device {
 public:
  virtual ~Device() = default;
  virtual const char* name() const = 0;
  // Called by the haptic loop (or the lesson runner) at time t_s since the task started.
  virtual ToolCommand read(double t_s) = 0;
  // The shaped force to render (N). Real devices send it to the motors.
  virtual void write_force(const Vec3d& force_N) = 0;
  virtual double max_force_N() const = 0;
  // The stiffness the device renders stably at its servo rate (N/m, the maker's rating); it
  // sizes the virtual coupling. Default: a desktop 3-DoF stylus device (about 1 N/mm).
  virtual double max_stiffness_N_m() const { return 1000.0; }
};

// Keyframes of a scripted device: linear interpolation between them, last one held.
struct Keyframe {
  double t_s = 0.0;
  Vec3d value{0, 0, 0};  // offset (m) or force (N)
};

// A YAML timeline (see docs/lessons.md, "device scripts"), one per task.
class ScriptedDevice final : public Device {
 public:
  ScriptedDevice(std::vector<Keyframe> keys, bool force_mode, double max_force_N);
  const char* name() const override { return "scripted"; }
  ToolCommand read(double t_s) override;
  void write_force(const Vec3d& force_N) override;
  double max_force_N() const override { return max_force_N_; }
  double duration_s() const { return keys_.empty() ? 0.0 : keys_.back().t_s; }
  // What the device was sent: peak magnitude and the last value (for tests and reports).
  double peak_sent_N() const { return peak_sent_N_; }
  const Vec3d& last_sent_N() const { return last_sent_N_; }

 private:
  std::vector<Keyframe> keys_;
  bool force_mode_;
  double max_force_N_;
  double peak_sent_N_ = 0.0;
  Vec3d last_sent_N_{0, 0, 0};
};

// The mouse as a virtual device: the UI thread drags on the screen plane and sets the offset;
// the loop reads it through atomics. The force it "renders" is shown as an arrow and a number.
class MouseDevice final : public Device {
 public:
  explicit MouseDevice(double max_force_N) : max_force_N_(max_force_N) {}
  const char* name() const override { return "mouse"; }
  ToolCommand read(double t_s) override;
  void write_force(const Vec3d& force_N) override;
  double max_force_N() const override { return max_force_N_; }
  // UI thread:
  void set(const Vec3d& offset_m, bool engaged);
  Vec3d force() const;

 private:
  double max_force_N_;
  std::atomic<double> ox_{0}, oy_{0}, oz_{0}, fx_{0}, fy_{0}, fz_{0};
  std::atomic<bool> engaged_{false};
};

// Clamp to the device limit and ramp on contact: the force grows linearly from 0 to full over
// ramp_s after contact begins, so a grasp never starts with a step (a jolt in the hand).
struct ForceShaper {
  double max_force_N = 4.0;
  double ramp_s = 0.05;
  double contact_start_s = -1.0;
  bool clamped = false;  // last call limited the force
  Vec3d shape(const Vec3d& force_N, bool contact, double t_s);
};

// Single-writer sequence lock for a trivially copyable value: the writer never waits; a reader
// that overlaps a write retries a few times and otherwise keeps its previous value.
template <class T>
class SeqLock {
 public:
  void store(const T& v) {
    const uint32_t s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    std::memcpy(static_cast<void*>(&data_), &v, sizeof(T));
    std::atomic_thread_fence(std::memory_order_release);
    seq_.store(s + 2, std::memory_order_release);
  }
  bool load(T& out) const {
    for (int attempt = 0; attempt < 4; ++attempt) {
      const uint32_t s0 = seq_.load(std::memory_order_acquire);
      if (s0 & 1u) continue;
      T copy;
      std::memcpy(static_cast<void*>(&copy), &data_, sizeof(T));
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == s0) {
        out = copy;
        return s0 != 0;
      }
    }
    return false;
  }

 private:
  std::atomic<uint32_t> seq_{0};
  T data_{};
};

struct HapticStats {
  int64_t cycles = 0;
  int64_t model_ticks = 0;      // ticks whose force was computed from a tissue model
  int64_t model_updates = 0;    // local models received from the physics
  double force_jump_max_N = 0;  // largest change of the device force between two ticks in contact
  double period_us_p50 = 0, period_us_p99 = 0, period_us_max = 0, period_us_mean = 0;
  int64_t late_2ms = 0;  // periods longer than 2 ms
  double period_us_p999 = 0;
  double peak_force_N = 0;  // largest shaped force sent
  bool realtime = false;    // SCHED_FIFO granted
  bool memory_locked = false;
  std::string message;  // why real time or locking was refused
};

class HapticLoop {
 public:
  // Reserves room for `max_cycles` period samples up front (no allocation while running).
  // The virtual coupling is sized from device.max_stiffness_N_m() and rate_hz; probe = true
  // makes the tool a probe tip that presses on surfaces instead of a grasp.
  HapticLoop(Device& device, ForceShaper shaper, int64_t max_cycles, double rate_hz = 1000.0, bool probe = false);
  ~HapticLoop();
  // cpu >= 0: the loop's thread runs on that core only (see CpuPlan).
  void start(bool want_realtime, int cpu = -1);
  void stop();
  bool running() const { return running_.load(); }

  // Physics side (another thread):
  bool latest_command(ToolCommand& out) const { return command_.load(out); }
  // A local model of the tissue (CouplingPhysics::local_model) after each physics step.
  void publish(const LocalModel& model) { model_.store(model); }
  // A bare reaction without stiffness: the loop holds it (zero-order hold; not a model).
  void publish(const ToolFeedback& fb);
  const HapticCoupling& coupling() const { return coupling_; }

  // One tick at time t_s (the thread calls it every period; a headless replay calls it itself,
  // without start()): newest model -> device read -> coupling -> shaper -> device force.
  Vec3d tick(double t_s);

  HapticStats stats() const;  // after stop()

 private:
  void run();
  Device& device_;
  ForceShaper shaper_;
  HapticCoupling coupling_;
  double period_ns_;
  std::vector<int64_t> periods_ns_;
  int64_t cycles_ = 0;
  double peak_force_N_ = 0, force_jump_max_N_ = 0;
  int64_t model_ticks_ = 0, model_updates_ = 0;
  uint64_t feedback_serial_ = 0;  // publish(ToolFeedback) numbers its models (one writer)
  uint64_t serial_ = 0;           // serial of the last model handed to the coupling
  Vec3d last_f_{0, 0, 0};
  bool last_contact_ = false;
  SeqLock<ToolCommand> command_;
  SeqLock<LocalModel> model_;
  std::atomic<bool> running_{false}, stop_{false};
  std::thread thread_;
  bool want_realtime_ = false, realtime_ = false, locked_ = false;
  int cpu_ = -1;
  std::string message_;
};

// Tries mlockall(MCL_CURRENT | MCL_FUTURE); returns false with the reason.
bool lock_memory(std::string& why);

// Which cores the threads use. The haptic loop shares one core with the physics thread, which
// keeps that core busy: on a virtual machine an idle core is halted and wakes late (a bare 1 kHz
// loop on an idle core here: max period 4.4 ms; beside a busy thread: 1.7 ms). The renderer (and
// llvmpipe's threads, which inherit the affinity of the thread that creates the context) gets
// the other cores. With a single allowed core nothing is pinned (haptic_cpu = -1).
struct CpuPlan {
  int haptic_cpu = -1;           // haptic loop and physics thread
  std::vector<int> render_cpus;  // everything else
};
CpuPlan plan_cpus();
// Restricts the calling thread to `cpus` (no-op when empty); false if the kernel refused.
bool pin_current_thread(const std::vector<int>& cpus);
// The same for one core (no-op when cpu < 0, as CpuPlan::haptic_cpu is without a plan).
bool pin_current_thread(int cpu);

}  // namespace softatlas::app
