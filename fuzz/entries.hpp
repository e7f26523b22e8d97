// The readers of outside data, one entry per fuzz target: each writes the input where the reader
// expects a file (a scratch folder per process) and runs the same code path as `softatlas`.
// Used by the libFuzzer targets (fuzz/fuzz_target.cpp) and by the regression test that replays
// tests/data/fuzz/TARGET/* in the normal build (tests/fuzz/regression_test.cpp).
#pragma once

#include <string>
#include <vector>

namespace softatlas::fuzz {

// nifti, nrrd, metaimage, dicom, mesh_obj, mesh_ply, mesh_stl, mesh_off, organ_set, lesson,
// device_script, seeds, build_yaml.
const std::vector<std::string>& targets();

// Feeds one input to the reader of `target`. Returns normally when the input is accepted and
// throws softatlas::InputError when it is rejected; anything else (another exception, a crash,
// a sanitizer report) is a bug.
void feed(const std::string& target, const std::string& bytes);

// The part of feed() for the readers of volumes, meshes and organ sets (fuzz/readers.cpp):
// false when `target` is not one of them.
bool feed_reader(const std::string& target, const std::string& bytes);
// The same for lessons and device scripts (fuzz/lessons.cpp).
bool feed_lesson(const std::string& target, const std::string& bytes);
// The same for seed files (fuzz/seeds.cpp).
bool feed_seeds(const std::string& target, const std::string& bytes);
// The same for build.yaml (fuzz/build_config.cpp).
bool feed_build_config(const std::string& target, const std::string& bytes);

// Scratch folder of this process (created on first use, removed at exit), and a file writer.
const std::string& scratch();
void write_input(const std::string& path, const std::string& bytes);

}  // namespace softatlas::fuzz
