// Contact between organs (contact.cpp): organs do not pass through each other.
//
//   detection   every step, organs whose bounding boxes (grown by the contact depth) overlap
//               form pairs; their faces go into one spatial hash grid by centroid; each vertex of
//               a paired organ inside a partner's box finds its nearest partner face. It
//               penetrates when it lies behind that face (the face normal, outward) by at most
//               ContactModel::depth_m. A vertex is looked up again only when what it and its
//               partners moved since its last lookup may have closed the distance found then
//               (conservative advancement); a vertex behind a face, every step.
//   response    position projection after the step's integration (position-based dynamics,
//               Mueller et al. 2007, the non-penetration constraint n . (p - sum_i b_i x_i) >= 0
//               of a vertex p and its face's closest point): a few Gauss-Seidel sweeps, movable
//               vertices weighted equally, fixed and rigid vertices immovable, tool-held ones
//               until the last round (the tool's hold is a proxy that contact stops, follow_contact).
//               Inelastic: what the projection moved loses its velocity into what it touched,
//               nothing is added (contact.cpp stop_approach, which says where and why; the
//               displacement added as velocity dx / h flung organs squeezed against a bone). On solid
//               organs the surface vertices' displacements move the lattice nodes (weighted by
//               the embedding), and the surface then follows the lattice.
//   exemptions  two organs overlapping deeper than 2 mm at rest (a vessel inside the liver) get no
//               contact between them; a vertex inside another organ at rest (the organ sets' surfaces touch and overlap
//               by a voxel or two; a vessel runs inside the liver) is never projected; a vertex
//               found deeper than depth_m (pushed through faster than contact could hold it, or
//               tunnelled in one step) is let go until it is outside again on its own side (the
//               straight way back to its rest position crosses no partner), so that the organ's
//               elasticity brings it back rather than contact trapping it on the far side.
//               Tool-held vertices are never let go: they give way in the last projection round.
// Everything the step uses is sized by compile() and make_work(); contact_pass() does not allocate.
#pragma once

#include <cstdint>
#include <vector>

namespace softatlas::sim {

struct Model;
struct State;
struct Work;

struct ContactModel {
  bool on = false;
  double depth_m = 3e-3;              // deepest penetration projected out; deeper ones are let go
  double cell_m = 0.0;                // hash grid cell size
  int32_t table_size = 0;             // hash grid buckets (power of two)
  std::vector<int8_t> organ_sign;     // +1 when the organ's faces are outward, -1 inward
  std::vector<uint8_t> vert_movable;  // 0: fixed vertex or rigid organ
  std::vector<uint8_t> rest_inside;   // per vertex: inside another organ at rest (never projected)
  std::vector<uint8_t> joined;        // #organs^2: overlapping deeper than 2 mm at rest, no contact
};

// Per step scratch (sized by make_work; empty when contact is off).
struct ContactWork {
  std::vector<double> box;            // #organs * 6 (min x y z, max x y z) this step
  std::vector<uint8_t> organ_paired;  // #organs: in some pair this step
  std::vector<uint8_t> pair;          // #organs^2: a and b are paired
  std::vector<int32_t> bucket_start;  // table_size + 1
  std::vector<int32_t> bucket_face;   // #faces in the grid, by bucket
  std::vector<int32_t> face_bucket;   // #faces: its bucket, -1 when not in the grid
  std::vector<double> face_sphere;    // #faces * 4: centroid and radius this step
  std::vector<int32_t> big_face;      // faces larger than a cell (not in the grid), nbig of them
  int32_t nbig = 0;
  std::vector<int32_t> c_vert, c_face;   // contacts of this step: vertex, face
  std::vector<double> c_bary, c_normal;  // #contacts * 3
  std::vector<double> saved;             // #verts * 3 positions before the projection
  std::vector<uint8_t> weight;           // #verts: movable this step (tool-held vertices are not)
  std::vector<uint8_t> touched;          // #verts: moved by the projection
  std::vector<double> held_before;       // #verts * 3: held vertices' positions before the projection
  // Conservative advancement (contact_pass): a vertex is looked up only when what it and its
  // partners moved since its last lookup may have closed the distance found then.
  std::vector<double> clear;         // #verts: distance to partner faces left, as of this step
  std::vector<double> last_x;        // #verts * 3: positions at the last detection
  std::vector<double> moved;         // #verts: moved since the last detection
  std::vector<double> organ_moved;   // #organs: the most any of its vertices moved
  std::vector<uint8_t> pair_before;  // #organs^2: the pairs the distances were found against
  std::vector<double> node_acc;      // solid lattice nodes: #nodes * 4 (dx dy dz, weight)
  std::vector<uint8_t> node_stop;    // solid lattice nodes: moved for a penetrating vertex
  double face_radius = 0.0;          // largest centroid-to-corner distance in the grid this step
};

// Compiles contact for a model (after its organs and solids): orientation signs, movability,
// the vertices inside another organ at rest. Leaves model.contact.on false when off or when the
// model has fewer than two organs.
void compile_contact(bool on, Model& model);
ContactWork make_contact_work(const Model& model);

// One step's detection and projection on state positions; returns the number of contacts.
int contact_pass(const Model& model, State& state, Work& work);

// Measurement: the deepest penetration (m) of any vertex into another organ (nearest face at any
// distance, behind it), leaving out vertices inside another organ at rest. Allocates.
double max_penetration(const Model& model, const State& state, int32_t* vertex = nullptr,
                       int32_t* into_organ = nullptr);

}  // namespace softatlas::sim
