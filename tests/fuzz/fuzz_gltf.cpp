// libFuzzer target: the glTF 2.0 character loader (loadGltf) on arbitrary bytes, binary (.glb) or text (.gltf).
#include <cstring>

#include "fuzz_support.h"
#include "myoskin/io.h"

using namespace myoskin;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const bool binary = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  const std::string path = fuzz::writeScratch(binary ? "character.glb" : "character.gltf", data, size);
  fuzz::expectInputErrorOnly([&] {
    const Character c = loadGltf(path);
    // Accepted: a valid character (the loader validated it; check what the pipeline relies on).
    validateCharacter(c);
    fuzz::requireFinite(c.mesh.vertices, "loaded vertices");
    if (c.mesh.vertices.rows() == 0 || c.mesh.triangles.rows() == 0) fuzz::fail("accepted an empty mesh");
    if (static_cast<int>(c.sourceToWelded.size()) != c.sourceVertexCount) fuzz::fail("sourceToWelded size");
    for (int w : c.sourceToWelded)
      if (w < 0 || w >= c.mesh.vertices.rows()) fuzz::fail("sourceToWelded out of range");
  });
  return 0;
}
