// Where the atlas stands in the room: organ-set coordinates (RAS, metres) <-> three.js / WebXR
// world coordinates (metres, +Y up, the user at the origin looking along -Z).
//
//   world = C + s R (p - c),  R: (x, y, z)_RAS -> (-x, z, y)
//
// R turns the patient's anterior (+y) towards the user (+Z) and superior (+z) up (+Y); the
// patient's right (+x) is then on the user's left, as in an anterior view (det R = +1). c is the
// centre of the organs' bounding box, C a point 50 cm in front of a standing user at chest height, s a
// little larger than life so that students see the organs well at arm's length.
import * as THREE from 'three';

export const WORLD_SCALE = 1.5;
export const WORLD_CENTRE = [0, 1.4, -0.5];

export class AtlasFrame {
  constructor(vertices) {
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < vertices.length; i += 3)
      for (let k = 0; k < 3; ++k) lo[k] = Math.min(lo[k], vertices[i + k]), hi[k] = Math.max(hi[k], vertices[i + k]);
    this.c = lo.map((v, k) => (v + hi[k]) / 2);
    this.s = WORLD_SCALE;
    this.centreWorld = new THREE.Vector3(...WORLD_CENTRE);
  }

  matrix() {
    const [cx, cy, cz] = this.c, s = this.s, C = this.centreWorld;
    // rows: X = -s (x - cx) + Cx, Y = s (z - cz) + Cy, Z = s (y - cy) + Cz
    return new THREE.Matrix4().set(
      -s, 0, 0, s * cx + C.x,
      0, 0, s, -s * cz + C.y,
      0, s, 0, -s * cy + C.z,
      0, 0, 0, 1);
  }

  toWorld(p) {
    const s = this.s, C = this.centreWorld;
    return new THREE.Vector3(C.x - s * (p[0] - this.c[0]), C.y + s * (p[2] - this.c[2]), C.z + s * (p[1] - this.c[1]));
  }

  toSet(w) {
    const s = this.s, C = this.centreWorld;
    return [this.c[0] - (w.x - C.x) / s, this.c[1] + (w.z - C.z) / s, this.c[2] + (w.y - C.y) / s];
  }

  dirToSet(d) { return [-d.x / this.s, d.z / this.s, d.y / this.s]; }

  // The functions below take the organ's positions p (#V*3, organ-set frame) and `used`, the
  // vertices that faces use (the core reports unused source vertices as (0, 0, 0)).
  centroid(p, used) {
    let x = 0, y = 0, z = 0;
    for (const v of used) x += p[3 * v], y += p[3 * v + 1], z += p[3 * v + 2];
    const n = Math.max(1, used.length);
    return [x / n, y / n, z / n];
  }

  // A point of the organ's anterior surface (world): the most anterior vertex within 15 mm
  // (organ-set units) of the line through the organ's centroid along the anterior direction.
  anteriorPoint(p, used) {
    const [cx, , cz] = this.centroid(p, used);
    let best = -1, bestAll = -1;
    for (const v of used) {
      const i = 3 * v;
      if (bestAll < 0 || p[i + 1] > p[bestAll + 1]) bestAll = i;
      const dx = p[i] - cx, dz = p[i + 2] - cz;
      if (dx * dx + dz * dz < 0.015 * 0.015 && (best < 0 || p[i + 1] > p[best + 1])) best = i;
    }
    const i = best >= 0 ? best : bestAll;
    return this.toWorld([p[i], p[i + 1], p[i + 2]]);
  }

  // Distance (world metres) from a world point to the organ's nearest vertex.
  nearestWorldDistance(p, used, w) {
    const q = this.toSet(w);
    let d2 = Infinity;
    for (const v of used) {
      const i = 3 * v;
      const dx = p[i] - q[0], dy = p[i + 1] - q[1], dz = p[i + 2] - q[2];
      d2 = Math.min(d2, dx * dx + dy * dy + dz * dz);
    }
    return Math.sqrt(d2) * this.s;
  }
}
