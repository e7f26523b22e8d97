// `softatlas export SET --web DIR`: the atlas as a static WebXR page (docs/web.md).
#pragma once

#include <string>

namespace softatlas::pipeline {

// Where the built page (scripts/build-web) is: $SOFTATLAS_WEB_DIST if set, else the build tree's
// web/dist. Empty if neither holds index.html.
std::string web_dist_folder();

// Writes DIR: the page (index.html, app.js, worker.js, softatlas_sim.mjs + .wasm copied from `dist`), the
// atlas as atlas.glb (export_gltf), scene.json (the organ set's physics scene: SI units, the
// sim::SceneDesc the native programs build) and lessons.json (the lessons whose organ_set is
// SET, from SET/lessons and SET/../lessons). Written into a temporary sibling folder, then
// renamed; an existing DIR is replaced only if it is a previous web export (has scene.json).
void export_web(const std::string& set_folder, const std::string& out_folder, const std::string& dist);

}  // namespace softatlas::pipeline
