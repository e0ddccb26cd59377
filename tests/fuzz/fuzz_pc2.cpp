// libFuzzer target: the PC2 point-cache reader (readPC2). Accepted caches must match their header.
#include "fuzz_support.h"
#include "myoskin/skinning.h"

using namespace myoskin;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = fuzz::writeScratch("cache.pc2", data, size);
  fuzz::expectInputErrorOnly([&] {
    const PointCache cache = readPC2(path);
    if (cache.numPoints < 0) fuzz::fail("negative point count accepted");
    size_t floats = 0;
    for (const PointsF& f : cache.frames) {
      if (f.rows() != cache.numPoints) fuzz::fail("frame size differs from the header");
      floats += static_cast<size_t>(f.size());
    }
    if (32 + 4 * floats != size) fuzz::fail("frames do not account for the file's bytes");
  });
  return 0;
}
