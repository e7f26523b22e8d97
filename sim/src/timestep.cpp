// The scene's time step when the caller leaves it to the models (SceneDesc::dt_s = 0). The solid
// model is an implicit projective-dynamics step whose cost does not depend on dt (solid.hpp), so
// a scene of solid organs steps at kSolidStep_s and reaches real time with room to spare; the
// surface models (tmsm, cmsm, nmsm, flexion) keep the paper's 1 ms, which their explicit
// integrators and the guard are sized for. One surface organ in the scene sets the step for all;
// rigid organs (bone) never move and do not count.
#include "softatlas/sim/sim.hpp"

namespace softatlas::sim {

double recommended_dt_s(const SceneDesc& scene) {
  bool any = false;
  for (const OrganDesc& o : scene.organs) {
    const bool moves = o.material.model != ModelKind::rigid &&  // bone, or fixed everywhere
                       o.fixed.size() < o.vertices.size() / 3;
    if (!moves) continue;
    any = true;
    if (o.material.model != ModelKind::solid) return kSurfaceStep_s;
  }
  return any ? kSolidStep_s : kSurfaceStep_s;
}

}  // namespace softatlas::sim
