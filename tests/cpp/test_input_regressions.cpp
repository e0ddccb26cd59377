// Every input that once crashed a reader (tests/fuzz/corpus/<target>/crash-*, found by the fuzzers and the
// sanitizer build) is refused with an InputError that says why, in the product build too (the fuzz tier replays
// them under ASan/UBSan in the sanitizer build only).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "myoskin/errors.h"
#include "myoskin/io.h"
#include "myoskin/skinning.h"

using namespace myoskin;
namespace fs = std::filesystem;

namespace {

const fs::path kCorpus = fs::path(__FILE__).parent_path().parent_path() / "fuzz" / "corpus";

std::vector<fs::path> crashInputs(const std::string& target) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(kCorpus / target))
    if (e.path().filename().string().rfind("crash-", 0) == 0) out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

std::string readText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

template <typename F>
void expectRefused(const fs::path& input, F&& load) {
  try {
    load();
    ADD_FAILURE() << input.filename() << " was accepted";
  } catch (const InputError& e) {
    EXPECT_GT(std::string(e.what()).size(), 20u) << input.filename();
    std::printf("%s: %s\n", input.filename().c_str(), e.what());
  }
}

}  // namespace

TEST(InputRegressions, CrashInputsAreRefusedWithAReason) {
  int n = 0;
  for (const fs::path& p : crashInputs("pc2")) expectRefused(p, [&] { readPC2(p.string()); }), ++n;
  for (const fs::path& p : crashInputs("muscles_json")) expectRefused(p, [&] { musclesFromJson(readText(p)); }), ++n;
  for (const fs::path& p : crashInputs("gltf")) {
    // The loader decides binary or text by the magic; the name's extension only must not say .glb for text.
    const fs::path copy = fs::temp_directory_path() / ("myoskin_regression_" + p.filename().string());
    fs::copy_file(p, copy, fs::copy_options::overwrite_existing);
    expectRefused(p, [&] { loadGltf(copy.string()); }), ++n;
    fs::remove(copy);
  }
  for (const fs::path& p : crashInputs("obj")) {
    const std::string text = readText(p);
    const size_t cut = text.find("\n#skeleton\n");
    const fs::path dir = fs::temp_directory_path() / "myoskin_regression_obj";
    fs::create_directories(dir);
    std::ofstream(dir / "c.obj", std::ios::binary) << text.substr(0, cut);
    std::ofstream(dir / "c.skeleton.json", std::ios::binary)
        << (cut == std::string::npos ? std::string() : text.substr(cut + 11));
    expectRefused(p, [&] { loadObjWithSkeleton((dir / "c.obj").string(), (dir / "c.skeleton.json").string()); }), ++n;
    fs::remove_all(dir);
  }
  EXPECT_GE(n, 5) << "the regression inputs are missing from " << kCorpus;
}
