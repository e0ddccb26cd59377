// libFuzzer target: muscles.json (musclesFromJson). Accepted muscles must write back and read again unchanged.
#include "fuzz_support.h"
#include "myoskin/io.h"

using namespace myoskin;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  fuzz::expectInputErrorOnly([&] {
    const std::vector<Muscle> muscles = musclesFromJson(text);
    const std::string written = musclesToJson(muscles);
    std::vector<Muscle> again;
    try {
      again = musclesFromJson(written);
    } catch (const InputError& e) {
      fuzz::fail(std::string("accepted muscles do not read back: ") + e.what());
    }
    if (again.size() != muscles.size()) fuzz::fail("muscle count changed in a round trip");
    if (musclesToJson(again) != written) fuzz::fail("muscles changed in a round trip");
  });
  return 0;
}
