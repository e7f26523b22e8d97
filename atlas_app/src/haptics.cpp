#include "softatlas/app/haptics.hpp"

#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

namespace softatlas::app {

ScriptedDevice::ScriptedDevice(std::vector<Keyframe> keys, bool force_mode, double max_force_N)
    : keys_(std::move(keys)), force_mode_(force_mode), max_force_N_(max_force_N) {}

ToolCommand ScriptedDevice::read(double t_s) {
  ToolCommand c;
  c.time_s = t_s;
  c.force_mode = force_mode_;
  c.engaged = !keys_.empty();
  Vec3d v{0, 0, 0};
  if (!keys_.empty()) {
    if (t_s <= keys_.front().t_s)
      v = keys_.front().value;
    else if (t_s >= keys_.back().t_s)
      v = keys_.back().value;
    else {
      const auto it =
          std::upper_bound(keys_.begin(), keys_.end(), t_s, [](double t, const Keyframe& k) { return t < k.t_s; });
      const Keyframe& b = *it;
      const Keyframe& a = *(it - 1);
      const double w = (t_s - a.t_s) / std::max(b.t_s - a.t_s, 1e-12);
      for (int k = 0; k < 3; ++k) v[k] = a.value[k] + w * (b.value[k] - a.value[k]);
    }
  }
  if (force_mode_)
    c.force_N = v;
  else
    c.offset_m = v;
  return c;
}

void ScriptedDevice::write_force(const Vec3d& f) {
  last_sent_N_ = f;
  peak_sent_N_ = std::max(peak_sent_N_, std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]));
}

ToolCommand MouseDevice::read(double t_s) {
  ToolCommand c;
  c.time_s = t_s;
  c.offset_m = {ox_.load(std::memory_order_relaxed), oy_.load(std::memory_order_relaxed),
                oz_.load(std::memory_order_relaxed)};
  c.engaged = engaged_.load(std::memory_order_acquire);
  return c;
}

void MouseDevice::write_force(const Vec3d& f) {
  fx_.store(f[0], std::memory_order_relaxed);
  fy_.store(f[1], std::memory_order_relaxed);
  fz_.store(f[2], std::memory_order_relaxed);
}

void MouseDevice::set(const Vec3d& offset_m, bool engaged) {
  ox_.store(offset_m[0], std::memory_order_relaxed);
  oy_.store(offset_m[1], std::memory_order_relaxed);
  oz_.store(offset_m[2], std::memory_order_relaxed);
  engaged_.store(engaged, std::memory_order_release);
}

Vec3d MouseDevice::force() const { return {fx_.load(), fy_.load(), fz_.load()}; }

Vec3d ForceShaper::shape(const Vec3d& f, bool contact, double t_s) {
  clamped = false;
  if (!contact) {
    contact_start_s = -1.0;
    return {0, 0, 0};
  }
  if (contact_start_s < 0) contact_start_s = t_s;
  const double ramp = ramp_s > 0 ? std::clamp((t_s - contact_start_s) / ramp_s, 0.0, 1.0) : 1.0;
  Vec3d out{f[0] * ramp, f[1] * ramp, f[2] * ramp};
  const double mag = std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
  if (mag > max_force_N && mag > 0) {
    const double s = max_force_N / mag;
    for (double& c : out) c *= s;
    clamped = true;
  }
  return out;
}

bool lock_memory(std::string& why) {
  // Keep freed memory in the heap instead of returning it to the kernel: with every page locked,
  // malloc's mmap/munmap of large blocks (the renderer's per-frame buffers) would make the kernel
  // zero and populate pages and shoot down TLBs on every core, which delays the haptic thread's
  // wake-up on a non-preemptible kernel (docs/viewer.md: kernel samples 8.4 % -> 2.3 %, p99 of
  // the haptic period 1140 -> 1025 us).
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, -1);
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) return true;
  why = std::string("mlockall refused (") + std::strerror(errno) +
        "): raise RLIMIT_MEMLOCK (ulimit -l) or grant CAP_IPC_LOCK";
  return false;
}

HapticLoop::HapticLoop(Device& device, ForceShaper shaper, int64_t max_cycles, double rate_hz, bool probe)
    : device_(device),
      shaper_(shaper),
      coupling_(size_coupling(device.max_stiffness_N_m(), rate_hz), probe),
      period_ns_(1e9 / rate_hz) {
  periods_ns_.assign(static_cast<size_t>(std::max<int64_t>(max_cycles, 1)), 0);  // pre-faulted
}

HapticLoop::~HapticLoop() { stop(); }

void HapticLoop::publish(const ToolFeedback& fb) {
  LocalModel m;
  m.serial = ++feedback_serial_;
  m.valid = fb.contact;
  m.has_stiffness = false;  // R(p) = R0: the loop holds the reaction until the next one
  m.reaction0_N = fb.reaction_N;
  m.physics_time_s = fb.physics_time_s;
  model_.store(m);
}

CpuPlan plan_cpus() {
  CpuPlan plan;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) != 0) return plan;
  std::vector<int> cpus;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &set)) cpus.push_back(c);
  if (cpus.size() < 2) return plan;
  plan.haptic_cpu = cpus.back();
  cpus.pop_back();
  plan.render_cpus = cpus;
  return plan;
}

bool pin_current_thread(const std::vector<int>& cpus) {
  if (cpus.empty()) return true;
  cpu_set_t set;
  CPU_ZERO(&set);
  for (int c : cpus) CPU_SET(c, &set);
  return pthread_setaffinity_np(pthread_self(), sizeof set, &set) == 0;
}

bool pin_current_thread(int cpu) { return cpu < 0 || pin_current_thread(std::vector<int>{cpu}); }

void HapticLoop::start(bool want_realtime, int cpu) {
  if (running_.load()) return;
  want_realtime_ = want_realtime;
  cpu_ = cpu;
  stop_.store(false);
  cycles_ = 0;
  running_.store(true);
  thread_ = std::thread([this] { run(); });
}

void HapticLoop::stop() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
  running_.store(false);
}

Vec3d HapticLoop::tick(double t_s) {
  // 1. the newest tissue model (never waiting: a read that overlaps a write keeps the old one),
  // 2. device -> coupling -> force from the model at this tick's position, 3. proxy -> physics
  LocalModel model;
  if (model_.load(model) && model.serial != serial_) {
    serial_ = model.serial;
    coupling_.update(model, t_s);
    ++model_updates_;
  }
  ToolCommand cmd = device_.read(t_s);
  bool from_model = false;
  const Vec3d raw = coupling_.tick(cmd, t_s, from_model);
  command_.store(cmd);
  const Vec3d f = shaper_.shape(raw, cmd.contact, t_s);
  device_.write_force(f);
  model_ticks_ += from_model ? 1 : 0;
  if (cmd.contact && last_contact_) {
    const double d[3] = {f[0] - last_f_[0], f[1] - last_f_[1], f[2] - last_f_[2]};
    force_jump_max_N_ = std::max(force_jump_max_N_, std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
  }
  last_f_ = f;
  last_contact_ = cmd.contact;
  peak_force_N_ = std::max(peak_force_N_, std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]));
  return f;
}

void HapticLoop::run() {
  pin_current_thread(cpu_);
  if (want_realtime_) {
    sched_param sp{};
    sp.sched_priority = std::min(80, sched_get_priority_max(SCHED_FIFO));
    const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    realtime_ = err == 0;
    if (!realtime_)
      message_ = std::string("SCHED_FIFO refused (") + std::strerror(err) +
                 "): the haptic loop runs at normal priority; grant CAP_SYS_NICE or set "
                 "rtprio in /etc/security/limits.conf for a steady 1 kHz";
  }
  timespec next{};
  clock_gettime(CLOCK_MONOTONIC, &next);
  const int64_t period = static_cast<int64_t>(period_ns_);
  int64_t start_ns = next.tv_sec * 1000000000LL + next.tv_nsec;
  int64_t last_ns = start_ns;
  const int64_t capacity = static_cast<int64_t>(periods_ns_.size());
  while (!stop_.load(std::memory_order_relaxed)) {
    next.tv_nsec += period;
    while (next.tv_nsec >= 1000000000L) {
      next.tv_nsec -= 1000000000L;
      ++next.tv_sec;
    }
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
    timespec now{};
    clock_gettime(CLOCK_MONOTONIC, &now);
    const int64_t now_ns = now.tv_sec * 1000000000LL + now.tv_nsec;
    tick(static_cast<double>(now_ns - start_ns) * 1e-9);
    if (cycles_ < capacity) periods_ns_[static_cast<size_t>(cycles_)] = now_ns - last_ns;
    ++cycles_;
    last_ns = now_ns;
    // If we fell behind by more than a period (preempted), restart the schedule from now rather
    // than firing a burst of catch-up cycles.
    const int64_t next_ns = next.tv_sec * 1000000000LL + next.tv_nsec;
    if (now_ns - next_ns > period) next = now;
  }
  if (realtime_) {
    sched_param sp{};
    pthread_setschedparam(pthread_self(), SCHED_OTHER, &sp);
  }
}

HapticStats HapticLoop::stats() const {
  HapticStats s;
  s.cycles = cycles_;
  s.realtime = realtime_;
  s.memory_locked = locked_;
  s.message = message_;
  s.peak_force_N = peak_force_N_;
  s.model_ticks = model_ticks_;
  s.model_updates = model_updates_;
  s.force_jump_max_N = force_jump_max_N_;
  const int64_t n = std::min<int64_t>(cycles_, static_cast<int64_t>(periods_ns_.size()));
  if (n <= 1) return s;
  // The first period includes thread start-up; skip it.
  std::vector<int64_t> p(periods_ns_.begin() + 1, periods_ns_.begin() + n);
  std::sort(p.begin(), p.end());
  auto q = [&](double f) {
    return static_cast<double>(p[std::min(p.size() - 1, static_cast<size_t>(f * static_cast<double>(p.size())))]) *
           1e-3;
  };
  s.period_us_p50 = q(0.5);
  s.period_us_p99 = q(0.99);
  s.period_us_max = static_cast<double>(p.back()) * 1e-3;
  s.period_us_p999 = q(0.999);
  for (int64_t v : p) s.late_2ms += v > 2000000 ? 1 : 0;
  double sum = 0;
  for (int64_t v : p) sum += static_cast<double>(v);
  s.period_us_mean = sum / static_cast<double>(p.size()) * 1e-3;
  return s;
}

}  // namespace softatlas::app
