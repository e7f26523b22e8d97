// The physics core (sim/ compiled to WebAssembly by scripts/build-web) behind a small JS class.
// Used by the page's worker (physics_worker.js) and by tests/web/wasm_match.mjs under node.
// Coordinates are the organ set's frame (RAS) in metres, as in scene.json.

export class Physics {
  // `module` is the instantiated emscripten module (createSoftAtlasSim()); `scene` the parsed
  // scene.json. Throws Error with the core's InputError text when the scene does not compile.
  constructor(module, scene) {
    this.m = module;
    this.organNames = [];
    this.vertexCounts = [];
    const m = module;
    if (scene.softatlas_web_scene !== 1) throw new Error('scene.json: expected "softatlas_web_scene": 1');
    m._sa_reset();
    const s = scene.settings;
    const g = s.gravity_m_s2;
    this.#check(this.#withString(s.integrator, (p) =>
      m._sa_settings(p, s.dt_s, s.gravity ? 1 : 0, g[0], g[1], g[2], s.cg_iterations, s.cg_tolerance,
        s.guard ? 1 : 0, s.max_tool_force_N, s.max_substeps, s.allow_sleep ? 1 : 0, s.sleep_speed_m_s,
        s.sleep_steps)));
    const fields = m.UTF8ToString(m._sa_material_fields()).split(',');
    for (const o of scene.organs) {
      const mat = new Float64Array(fields.length);
      fields.forEach((f, i) => {
        if (typeof o.material[f] !== 'number') throw new Error(`scene.json: organs.${o.name}.material.${f}: expected a number`);
        mat[i] = o.material[f];
      });
      const v = this.#copy(Float64Array, o.vertices);
      const f = this.#copy(Int32Array, o.faces);
      const x = this.#copy(Int32Array, o.fixed);
      const mp = this.#copy(Float64Array, mat);
      const rc = this.#withString(o.name, (np) => this.#withString(o.material.model, (mm) =>
        m._sa_add_organ(np, v, o.vertices.length / 3, f, o.faces.length / 3, x, o.fixed.length, mm,
          o.material.elastica_p, mp, o.shown ? 1 : 0)));
      for (const p of [v, f, x, mp]) m._free(p);
      this.#check(rc);
    }
    for (const c of scene.connections)
      m._sa_add_connection(c.organ_a, c.vertex_a, c.organ_b, c.vertex_b, c.rest_length_m, c.stiffness);
    this.#check(m._sa_compile());
    this.dt = m._sa_dt();
    const n = m._sa_organ_count();
    this.countPtr = m._malloc(4);
    for (let i = 0; i < n; ++i) {
      this.organNames.push(m.UTF8ToString(m._sa_organ_name(i)));
      m._sa_positions(i, this.countPtr);
      this.vertexCounts.push(m.getValue(this.countPtr, 'i32'));
    }
  }

  organIndex(name) { return this.organNames.indexOf(name); }

  // n steps of sim::step(); returns the worst StepStatus (0 ok ... 3 restored).
  step(n) { return this.m._sa_step(n); }

  time() { return this.m._sa_time(); }

  // Positions of organ i (#V*3, source-mesh order = the glb's vertex order), copied into `out`
  // (Float64Array or Float32Array of 3*V) or a new Float64Array.
  positions(i, out) {
    const p = this.m._sa_positions(i, this.countPtr);
    const count = 3 * this.m.getValue(this.countPtr, 'i32');
    const view = this.m.HEAPF64.subarray(p / 8, p / 8 + count);
    if (!out) return Float64Array.from(view);
    out.set(view);
    return out;
  }

  grab(i, point, radiusM) { return this.m._sa_grab(i, point[0], point[1], point[2], radiusM); }
  move(offset) { this.m._sa_move(offset[0], offset[1], offset[2]); }
  release() { this.m._sa_release(); }
  reaction() { return [0, 1, 2].map((c) => this.m._sa_reaction(c)); }
  awake(i) { return this.m._sa_organ_awake(i) !== 0; }
  maxDisplacement(i) { return this.m._sa_max_displacement(i); }
  explain() { return this.m.UTF8ToString(this.m._sa_explain()); }

  #check(rc) {
    if (rc < 0) throw new Error(this.m.UTF8ToString(this.m._sa_error()));
  }

  #withString(text, fn) {
    const n = this.m.lengthBytesUTF8(text) + 1;
    const p = this.m._malloc(n);
    this.m.stringToUTF8(text, p, n);
    try {
      return fn(p);
    } finally {
      this.m._free(p);
    }
  }

  #copy(Type, values) {
    const p = this.m._malloc(Math.max(1, values.length) * Type.BYTES_PER_ELEMENT);
    const heap = Type === Float64Array ? this.m.HEAPF64 : this.m.HEAP32;
    heap.set(values, p / Type.BYTES_PER_ELEMENT);
    return p;
  }
}
