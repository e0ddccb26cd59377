// libFuzzer target: an OBJ mesh plus its skeleton JSON (loadObjWithSkeleton). The input is the OBJ text, then a
// line "#skeleton", then the skeleton JSON (without the separator: all OBJ, an empty skeleton).
#include <string_view>

#include "fuzz_support.h"
#include "myoskin/io.h"

using namespace myoskin;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const std::string_view separator = "\n#skeleton\n";
  const size_t cut = text.find(separator);
  const std::string_view obj = text.substr(0, cut);
  const std::string_view skeleton = cut == std::string_view::npos ? std::string_view() : text.substr(cut + separator.size());
  const std::string objPath = fuzz::writeScratch("character.obj", reinterpret_cast<const uint8_t*>(obj.data()), obj.size());
  const std::string skeletonPath =
      fuzz::writeScratch("character.skeleton.json", reinterpret_cast<const uint8_t*>(skeleton.data()), skeleton.size());
  fuzz::expectInputErrorOnly([&] {
    const Character c = loadObjWithSkeleton(objPath, skeletonPath);
    validateCharacter(c);
    fuzz::requireFinite(c.mesh.vertices, "loaded vertices");
    if (c.mesh.vertices.rows() == 0 || c.mesh.triangles.rows() == 0) fuzz::fail("accepted an empty mesh");
    for (const Bone& b : c.skeleton.bones) {
      fuzz::requireFinite(b.rest, "bone '" + b.name + "' rest matrix");
      if (!(b.length() > 0)) fuzz::fail("bone '" + b.name + "' has zero length");
    }
  });
  return 0;
}
