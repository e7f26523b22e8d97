// What passes between a haptic device, the 1 kHz loop and the physics: the tool's command and
// the bare reaction feedback.
#pragma once

#include <array>
#include <cstdint>

namespace softatlas::app {

using Vec3d = std::array<double, 3>;

// What the device commands this instant. Positions are tool offsets from the grasp point (m);
// a force-mode device commands a force (N) instead of a position.
struct ToolCommand {
  double time_s = 0.0;
  Vec3d offset_m{0, 0, 0};
  Vec3d force_N{0, 0, 0};
  bool force_mode = false;
  bool engaged = false;  // button down / grasping
  // Filled by the haptic loop's coupling (virtual_coupling.hpp): where the physics should hold
  // the tissue (the proxy, tool frame), whether the tool touches it, and for a probe which
  // contact this is and where it began.
  Vec3d proxy_m{0, 0, 0};
  bool contact = false;
  uint32_t contact_id = 0;
  Vec3d contact_m{0, 0, 0};
};

struct ToolFeedback {
  Vec3d reaction_N{0, 0, 0};  // the core's tool_reaction (force of the organ on the tool)
  bool contact = false;
  double physics_time_s = 0.0;
};

}  // namespace softatlas::app
