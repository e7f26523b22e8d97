// libFuzzer entry: one executable per target (fuzz_TARGET, compiled with -DSOFTATLAS_FUZZ_TARGET).
// A rejected input (InputError) is the expected outcome; any other exception escapes and aborts,
// so libFuzzer records it as a crash.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "entries.hpp"
#include "softatlas/sim/error.hpp"

// DICOM slices are decoded in this process, not in a child, so that libFuzzer sees GDCM's
// coverage and crashes (pipeline/src/volume_io.cpp).
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  setenv("SOFTATLAS_DICOM_IN_PROCESS", "1", 1);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const std::string bytes(reinterpret_cast<const char*>(data), size);
#if defined(SOFTATLAS_FUZZ_READER)
    softatlas::fuzz::feed_reader(SOFTATLAS_FUZZ_TARGET, bytes);  // links only the reader sources
#elif defined(SOFTATLAS_FUZZ_LESSON)
    softatlas::fuzz::feed_lesson(SOFTATLAS_FUZZ_TARGET, bytes);  // the lesson sources and the readers
#elif defined(SOFTATLAS_FUZZ_SEEDS)
    softatlas::fuzz::feed_seeds(SOFTATLAS_FUZZ_TARGET, bytes);  // the segmentation sources and the readers
#else
    softatlas::fuzz::feed_build_config(SOFTATLAS_FUZZ_TARGET, bytes);  // build.yaml's reader
#endif
  } catch (const softatlas::InputError&) {}
  return 0;
}
