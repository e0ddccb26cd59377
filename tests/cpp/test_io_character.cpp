// Character loaders and writers: glTF (shared characters and a hand-built .glb), OBJ + skeleton JSON, bad inputs.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "myoskin/errors.h"
#include "myoskin/io.h"
#include "myoskin/mesh.h"
#include "test_support.h"

using namespace myoskin;
namespace fs = std::filesystem;

namespace {

// ============================================================================
// Helpers
// ============================================================================

std::string makehumanPath() {
  return test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
}
std::string lowpolyPath() {
  return test::sharedPath("characters/godot_male_base_mesh_lowpoly/male_base_mesh.glb");
}

// A fresh file path in the temp folder, unique per test.
std::string tempPath(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::temp_directory_path() / "myoskin_test_io_character";
  fs::create_directories(dir);
  return (dir / (std::string(info->test_suite_name()) + "_" + info->name() + "_" + name)).string();
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// Runs `f` and returns the InputError message; fails the test if nothing (or something else) is thrown.
template <typename F>
std::string inputErrorOf(F f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected InputError, got: " << e.what();
    return "";
  }
  ADD_FAILURE() << "expected InputError, nothing was thrown";
  return "";
}

// Checks the rest frame: orthonormal, right-handed, Y along head -> tail, origin at the head.
void expectBoneFrames(const Skeleton& s) {
  for (const Bone& b : s.bones) {
    const Mat3 r = b.rest.block<3, 3>(0, 0);
    EXPECT_LT((r.transpose() * r - Mat3::Identity()).norm(), 1e-9) << b.name;
    EXPECT_NEAR(r.determinant(), 1.0, 1e-9) << b.name;
    EXPECT_LT((r.col(1) - (b.tail - b.head).normalized()).norm(), 1e-9) << b.name;
    EXPECT_LT((b.rest.block<3, 1>(0, 3) - b.head).norm(), 1e-12) << b.name;
    EXPECT_GT(b.length(), 1e-6) << b.name;
  }
}

// Every vertex has weights summing to 1 and valid bone indices.
void expectNormalisedWeights(const Character& c) {
  ASSERT_TRUE(c.hasWeights());
  ASSERT_EQ(c.weights.numVertices(), c.mesh.numVertices());
  EXPECT_EQ(c.weights.influences(), 4);
  for (int v = 0; v < c.weights.numVertices(); ++v) {
    double sum = 0;
    for (int k = 0; k < c.weights.influences(); ++k) {
      const int j = c.weights.joints(v, k);
      const double w = c.weights.weights(v, k);
      if (j < 0) {
        EXPECT_EQ(w, 0.0);
        continue;
      }
      EXPECT_LT(j, c.skeleton.numBones());
      sum += w;
    }
    ASSERT_NEAR(sum, 1.0, 1e-6) << "vertex " << v;
  }
}

// The elbow (head of `forearm`) lies inside the bounding box of the skin dominated by the arm's two bones,
// and within a few centimetres of that skin (the low-poly arm is coarse).
void expectElbowInsideArm(const Character& c, const std::string& upper, const std::string& fore) {
  const int u = c.skeleton.find(upper), f = c.skeleton.find(fore);
  ASSERT_GE(u, 0);
  ASSERT_GE(f, 0);
  const Vec3 elbow = c.skeleton.bones[f].head;
  EXPECT_LT((c.skeleton.bones[u].tail - elbow).norm(), 0.02) << "upper arm ends at the elbow";
  Vec3 lo = Vec3::Constant(1e9), hi = Vec3::Constant(-1e9);
  double nearest = 1e9;
  int count = 0;
  for (int v = 0; v < c.mesh.numVertices(); ++v) {
    const int j = c.weights.joints(v, 0);  // dominant bone (slots are sorted by weight)
    if (j != u && j != f) continue;
    const Vec3 p = c.mesh.vertices.row(v).transpose();
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
    nearest = std::min(nearest, (p - elbow).norm());
    ++count;
  }
  ASSERT_GT(count, 10);
  EXPECT_TRUE((elbow.array() > lo.array()).all() && (elbow.array() < hi.array()).all())
      << "elbow " << elbow.transpose() << " outside [" << lo.transpose() << "] .. [" << hi.transpose() << "]";
  EXPECT_LT(nearest, 0.08);
}

// ============================================================================
// A hand-built .glb: interleaved attributes with byteStride, u8 indices at an offset, u16 joints,
// normalised u8 weights, skin joints listed child-first, a rotated root and an ignored mesh-node transform.
// ============================================================================

template <typename T>
void put(std::vector<unsigned char>& buf, T value) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  buf.insert(buf.end(), bytes, bytes + sizeof(T));
}

// The tetrahedron's bind-space vertices; the scene places them by the root's rotation R (90 deg about Z)
// and translation (1, 0, 0).
const double kTet[4][3] = {{0, 0, 0}, {0.2, 0, 0}, {0, 0.5, 0}, {0, 0.25, 0.2}};

Vec3 rootTransform(const Vec3& p) {
  return Vec3(-p.y(), p.x(), p.z()) + Vec3(1, 0, 0);
}

// Variants of the hand-built file.
struct TinyOptions {
  bool skinned = true;       // false: the mesh node has no "skin" (the skin still exists in the file)
  bool text = false;         // write .gltf + .bin instead of .glb
  int badIndex = -1;         // >= 0: this value replaces the last index
  bool nanPosition = false;  // vertex 3 gets a NaN coordinate
};

std::string writeTinyGlb(const TinyOptions& o = {}) {
  std::vector<unsigned char> bin;
  // Interleaved vertices: POSITION f32x3 (12) + JOINTS_0 u16x4 (8) + WEIGHTS_0 u8x4 normalised (4) = 24 bytes.
  const uint16_t joints[4][4] = {{1, 0, 0, 0}, {1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 0, 0}};
  const uint8_t weights[4][4] = {{255, 0, 0, 0}, {255, 0, 0, 0}, {128, 127, 0, 0}, {255, 0, 0, 0}};
  for (int v = 0; v < 4; ++v) {
    for (int k = 0; k < 3; ++k)
      put<float>(bin, o.nanPosition && v == 3 && k == 1 ? std::nanf("") : static_cast<float>(kTet[v][k]));
    for (int k = 0; k < 4; ++k) put<uint16_t>(bin, joints[v][k]);
    for (int k = 0; k < 4; ++k) put<uint8_t>(bin, weights[v][k]);
  }
  // 96 bytes so far; indices view starts at 96 with 4 junk bytes before the accessor's data (byteOffset 4).
  for (int k = 0; k < 4; ++k) put<uint8_t>(bin, 0xEE);
  uint8_t tris[12] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2};
  if (o.badIndex >= 0) tris[11] = static_cast<uint8_t>(o.badIndex);
  for (uint8_t i : tris) put<uint8_t>(bin, i);
  while (bin.size() % 4) put<uint8_t>(bin, 0);
  // Inverse bind matrices: IBM_j = World(joint_j)^-1 * R (so rest skinning gives R * v for every joint).
  const size_t ibmOffset = bin.size();
  Mat4 root = Mat4::Identity();
  root.block<3, 3>(0, 0) = Eigen::AngleAxisd(M_PI / 2, Vec3::UnitZ()).toRotationMatrix();
  root.block<3, 1>(0, 3) = Vec3(1, 0, 0);
  Mat4 b = Mat4::Identity();
  b.block<3, 1>(0, 3) = Vec3(0, 0.3, 0);
  const Mat4 worldA = root, worldB = root * b;
  for (const Mat4& w : {worldB, worldA}) {  // skin joints: [b, a]
    const Mat4 ibm = w.inverse() * root;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) put<float>(bin, static_cast<float>(ibm(r, c)));
  }
  nlohmann::json j = {
      {"asset", {{"version", "2.0"}}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0}}}}},
      {"nodes",
       {{{"name", "root"},
         {"rotation", {0, 0, std::sin(M_PI / 4), std::cos(M_PI / 4)}},
         {"translation", {1, 0, 0}},
         {"children", {1, 3}}},
        {{"name", "a"}, {"children", {2}}},
        {{"name", "b"}, {"translation", {0, 0.3, 0}}},
        {{"name", "body"}, {"mesh", 0}, {"skin", 0}, {"translation", {5, 5, 5}}}}},
      {"skins", {{{"joints", {2, 1}}, {"inverseBindMatrices", 3}}}},
      {"meshes",
       {{{"name", "tet"},
         {"primitives", {{{"attributes", {{"POSITION", 0}, {"JOINTS_0", 1}, {"WEIGHTS_0", 2}}}, {"indices", 4}}}}}}},
      {"buffers", {{{"byteLength", bin.size()}}}},
      {"bufferViews",
       {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 96}, {"byteStride", 24}},
        {{"buffer", 0}, {"byteOffset", 96}, {"byteLength", 16}},
        {{"buffer", 0}, {"byteOffset", ibmOffset}, {"byteLength", 128}}}},
      {"accessors",
       {{{"bufferView", 0},
         {"byteOffset", 0},
         {"componentType", 5126},
         {"count", 4},
         {"type", "VEC3"},
         {"min", {0, 0, 0}},
         {"max", {0.2, 0.5, 0.2}}},
        {{"bufferView", 0}, {"byteOffset", 12}, {"componentType", 5123}, {"count", 4}, {"type", "VEC4"}},
        {{"bufferView", 0},
         {"byteOffset", 20},
         {"componentType", 5121},
         {"normalized", true},
         {"count", 4},
         {"type", "VEC4"}},
        {{"bufferView", 2}, {"byteOffset", 0}, {"componentType", 5126}, {"count", 2}, {"type", "MAT4"}},
        {{"bufferView", 1}, {"byteOffset", 4}, {"componentType", 5121}, {"count", 12}, {"type", "SCALAR"}}}}};
  if (!o.skinned) j["nodes"][3].erase("skin");
  if (o.text) {
    const std::string binPath = tempPath("tiny.bin"), gltfPath = tempPath("tiny.gltf");
    std::ofstream(binPath, std::ios::binary).write(reinterpret_cast<const char*>(bin.data()), bin.size());
    j["buffers"][0]["uri"] = fs::path(binPath).filename().string();
    writeText(gltfPath, j.dump(1));
    return gltfPath;
  }
  std::string js = j.dump();
  while (js.size() % 4) js += ' ';
  std::vector<unsigned char> glb;
  put<uint32_t>(glb, 0x46546C67);
  put<uint32_t>(glb, 2);
  put<uint32_t>(glb, static_cast<uint32_t>(12 + 8 + js.size() + 8 + bin.size()));
  put<uint32_t>(glb, static_cast<uint32_t>(js.size()));
  put<uint32_t>(glb, 0x4E4F534A);
  glb.insert(glb.end(), js.begin(), js.end());
  put<uint32_t>(glb, static_cast<uint32_t>(bin.size()));
  put<uint32_t>(glb, 0x004E4942);
  glb.insert(glb.end(), bin.begin(), bin.end());
  const std::string path = tempPath("tiny.glb");
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(glb.data()), glb.size());
  return path;
}

}  // namespace

// ============================================================================
// glTF: the shared characters
// ============================================================================

TEST(LoadGltf, MakeHumanCountsTopologyAndBounds) {
  const std::string path = makehumanPath();
  MYOSKIN_REQUIRE_SHARED(path);
  LoadOptions options;
  options.requireWeights = true;
  const Character c = loadGltf(path, options);
  EXPECT_EQ(c.name, "makehuman_muscular_male");
  EXPECT_EQ(c.mesh.numVertices(), 13380);
  EXPECT_EQ(c.mesh.numTriangles(), 26756);
  EXPECT_EQ(c.sourceVertexCount, 13380);
  EXPECT_EQ(static_cast<int>(c.sourceToWelded.size()), 13380);
  EXPECT_EQ(c.skeleton.numBones(), 163);
  const TopologyReport t = analyzeTopology(c.mesh);
  EXPECT_TRUE(t.closed());
  EXPECT_TRUE(t.manifold());
  EXPECT_TRUE(t.oriented());
  EXPECT_EQ(t.components, 1);
  EXPECT_GT(enclosedVolume(c.mesh.vertices, c.mesh.triangles), 0.0);
  Vec3 lo, hi;
  boundingBox(c.mesh.vertices, lo, hi);
  EXPECT_NEAR(lo.x(), -0.604, 0.005);
  EXPECT_NEAR(hi.x(), 0.604, 0.005);
  EXPECT_NEAR(lo.y(), -0.819, 0.005);
  EXPECT_NEAR(hi.y(), 0.912, 0.005);
  EXPECT_NEAR(lo.z(), -0.095, 0.005);
  EXPECT_NEAR(hi.z(), 0.377, 0.005);
}

TEST(LoadGltf, MakeHumanSkeletonAndWeights) {
  const std::string path = makehumanPath();
  MYOSKIN_REQUIRE_SHARED(path);
  const Character c = loadGltf(path);
  for (const char* name : {"root", "spine01", "upperarm01.L", "lowerarm01.L", "upperleg01.R", "lowerleg01.R", "head"})
    EXPECT_GE(c.skeleton.find(name), 0) << name;
  EXPECT_EQ(c.skeleton.bones[0].name, "root");
  EXPECT_EQ(c.skeleton.bones[0].parent, -1);
  EXPECT_EQ(c.skeleton.bones[c.skeleton.find("lowerarm01.L")].parent, c.skeleton.find("upperarm02.L"));
  expectBoneFrames(c.skeleton);
  expectNormalisedWeights(c);
  expectElbowInsideArm(c, "upperarm02.L", "lowerarm01.L");
  expectElbowInsideArm(c, "upperarm02.R", "lowerarm01.R");
  expectElbowInsideArm(c, "upperleg02.L", "lowerleg01.L");  // the knee
  // Faces +Z (the feet point along +Z) with the character's left at +X, as the README says.
  const Bone& foot = c.skeleton.bones[c.skeleton.find("foot.L")];
  EXPECT_GT(foot.tail.z() - foot.head.z(), 2 * std::abs(foot.tail.x() - foot.head.x()));
  EXPECT_GT(c.skeleton.bones[c.skeleton.find("upperarm01.L")].head.x(), 0.1);
}

TEST(LoadGltf, LowpolyWeldsAndStandsUpright) {
  const std::string path = lowpolyPath();
  MYOSKIN_REQUIRE_SHARED(path);
  LoadOptions options;
  options.requireWeights = true;
  const Character c = loadGltf(path, options);
  EXPECT_EQ(c.sourceVertexCount, 1226);
  EXPECT_EQ(static_cast<int>(c.sourceToWelded.size()), 1226);
  EXPECT_EQ(c.mesh.numVertices(), 904);
  EXPECT_EQ(c.mesh.numTriangles(), 1804);
  EXPECT_EQ(c.skeleton.numBones(), 56);
  const TopologyReport t = analyzeTopology(c.mesh);
  EXPECT_TRUE(t.closed());
  EXPECT_TRUE(t.manifold());
  EXPECT_TRUE(t.oriented());
  EXPECT_EQ(t.components, 1);
  Vec3 lo, hi;
  boundingBox(c.mesh.vertices, lo, hi);
  EXPECT_NEAR(hi.y() - lo.y(), 1.95, 0.05);
  EXPECT_NEAR(lo.y(), -1.0, 0.05);
  // Facing: per glTF skinning every World(joint) * inverseBindMatrix is the identity here, so the stored vertices
  // are already scene positions and the body faces +X with the A-pose arms spread along Z (Blender 3.4.1's
  // importer shows the same). The README's "faces along Z" does not hold for a spec-conformant loader.
  EXPECT_GT(hi.z() - lo.z(), 1.5 * (hi.x() - lo.x()));
  const Skeleton& s = c.skeleton;
  ASSERT_GE(s.find("spine.005"), 0);
  EXPECT_GT(s.bones[s.find("spine.005")].head.y(), s.bones[s.find("spine")].head.y() + 0.4);  // head above pelvis
  const Vec3 forward = s.bones[s.find("toe.L")].head - s.bones[s.find("foot.L")].head;        // feet point forward
  EXPECT_GT(forward.x(), 3 * std::abs(forward.z())) << forward.transpose();
  const Vec3 left = Vec3::UnitY().cross(Vec3::UnitX());  // up x forward = -Z
  EXPECT_GT((s.bones[s.find("upper_arm.L")].head - s.bones[s.find("spine")].head).dot(left), 0.1);
  EXPECT_LT((s.bones[s.find("upper_arm.R")].head - s.bones[s.find("spine")].head).dot(left), -0.1);
}

TEST(LoadGltf, LowpolySkeletonAndWeights) {
  const std::string path = lowpolyPath();
  MYOSKIN_REQUIRE_SHARED(path);
  const Character c = loadGltf(path);
  for (const char* name : {"spine", "upper_arm.L", "forearm.L", "hand.L", "thigh.R", "shin.R", "foot.R"})
    EXPECT_GE(c.skeleton.find(name), 0) << name;
  EXPECT_EQ(c.skeleton.bones[c.skeleton.find("forearm.L")].parent, c.skeleton.find("upper_arm.L"));
  expectBoneFrames(c.skeleton);
  expectNormalisedWeights(c);
  expectElbowInsideArm(c, "upper_arm.L", "forearm.L");
  expectElbowInsideArm(c, "upper_arm.R", "forearm.R");
  expectElbowInsideArm(c, "thigh.L", "shin.L");
  // Every source vertex maps into the welded mesh at the same position.
  const Character raw = loadGltf(path, LoadOptions{0.0, false});
  for (int i = 0; i < c.sourceVertexCount; ++i)
    EXPECT_LT((c.mesh.vertices.row(c.sourceToWelded[i]) - raw.mesh.vertices.row(raw.sourceToWelded[i])).norm(), 1e-6);
}

TEST(LoadCharacter, DispatchesGlb) {
  const std::string path = lowpolyPath();
  MYOSKIN_REQUIRE_SHARED(path);
  EXPECT_EQ(loadCharacter(path).mesh.numVertices(), 904);
}

// ============================================================================
// glTF: accessor layouts, joint reordering, transforms
// ============================================================================

TEST(LoadGltf, HandBuiltGlbStridesOffsetsAndJointOrder) {
  const Character c = loadGltf(writeTinyGlb());
  ASSERT_EQ(c.mesh.numVertices(), 4);
  ASSERT_EQ(c.mesh.numTriangles(), 4);
  // Rest positions = root transform of the bind-space vertices; the mesh node's own (5,5,5) is ignored.
  for (int v = 0; v < 4; ++v)
    EXPECT_LT((c.mesh.vertices.row(v).transpose() - rootTransform(Vec3(kTet[v][0], kTet[v][1], kTet[v][2]))).norm(),
              1e-6)
        << v;
  // Skin order [b, a] becomes bones [a, b].
  ASSERT_EQ(c.skeleton.numBones(), 2);
  EXPECT_EQ(c.skeleton.bones[0].name, "a");
  EXPECT_EQ(c.skeleton.bones[1].name, "b");
  EXPECT_EQ(c.skeleton.bones[1].parent, 0);
  EXPECT_LT((c.skeleton.bones[0].head - Vec3(1, 0, 0)).norm(), 1e-12);
  EXPECT_LT((c.skeleton.bones[0].tail - Vec3(0.7, 0, 0)).norm(), 1e-12);  // single child: its head
  EXPECT_LT((c.skeleton.bones[1].tail - Vec3(0.4, 0, 0)).norm(), 1e-12);  // leaf: along Y, parent's length
  expectBoneFrames(c.skeleton);
  // Vertex 0: joint slot 1 of the skin (= a) with 255/255; vertex 2: 128/255 on b and 127/255 on a.
  EXPECT_EQ(c.weights.joints(0, 0), 0);
  EXPECT_DOUBLE_EQ(c.weights.weights(0, 0), 1.0);
  EXPECT_EQ(c.weights.joints(3, 0), 1);
  EXPECT_EQ(c.weights.joints(2, 0), 1);
  EXPECT_NEAR(c.weights.weights(2, 0), 128.0 / 255.0, 1e-12);
  EXPECT_EQ(c.weights.joints(2, 1), 0);
  EXPECT_NEAR(c.weights.weights(2, 1), 127.0 / 255.0, 1e-12);
  EXPECT_EQ(c.weights.joints(0, 1), -1);
}

TEST(LoadGltf, HandBuiltTextGltfWithExternalBuffer) {
  TinyOptions o;
  o.text = true;
  const Character c = loadCharacter(writeTinyGlb(o));
  ASSERT_EQ(c.mesh.numVertices(), 4);
  EXPECT_LT((c.mesh.vertices.row(2).transpose() - rootTransform(Vec3(0, 0.5, 0))).norm(), 1e-6);
  EXPECT_EQ(c.skeleton.numBones(), 2);
}

TEST(LoadGltf, UnskinnedMeshUsesItsNodeTransform) {
  TinyOptions o;
  o.skinned = false;
  const std::string path = writeTinyGlb(o);
  const Character c = loadGltf(path);
  EXPECT_FALSE(c.hasWeights());
  EXPECT_EQ(c.skeleton.numBones(), 2);  // the file's skin still gives the skeleton
  // World(body) = root * translate(5, 5, 5).
  EXPECT_LT((c.mesh.vertices.row(1).transpose() - rootTransform(Vec3(5.2, 5, 5))).norm(), 1e-6);
  LoadOptions options;
  options.requireWeights = true;
  EXPECT_NE(inputErrorOf([&] { loadGltf(path, options); }).find("skin"), std::string::npos);
}

TEST(LoadGltf, BadIndexAndNanPosition) {
  TinyOptions o;
  o.badIndex = 9;
  EXPECT_NE(inputErrorOf([&] { loadGltf(writeTinyGlb(o)); }).find("out of range"), std::string::npos);
  TinyOptions n;
  n.nanPosition = true;
  EXPECT_NE(inputErrorOf([&] { loadGltf(writeTinyGlb(n)); }).find("NaN"), std::string::npos);
}

// ============================================================================
// OBJ + skeleton JSON
// ============================================================================

TEST(ObjSkeleton, MakeHumanRoundTrip) {
  const std::string path = makehumanPath();
  MYOSKIN_REQUIRE_SHARED(path);
  const Character a = loadGltf(path);
  const std::string obj = tempPath("mh.obj"), skel = tempPath("mh.skeleton.json");
  writeObj(obj, a.mesh.vertices, a.mesh.triangles);
  writeSkeletonJson(skel, a);
  const Character b = loadCharacter(obj);  // finds mh.skeleton.json beside it
  ASSERT_EQ(b.mesh.numVertices(), a.mesh.numVertices());
  ASSERT_EQ(b.mesh.numTriangles(), a.mesh.numTriangles());
  EXPECT_LE((b.mesh.vertices - a.mesh.vertices).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_TRUE((b.mesh.triangles.array() == a.mesh.triangles.array()).all());
  ASSERT_EQ(b.skeleton.numBones(), a.skeleton.numBones());
  for (int i = 0; i < a.skeleton.numBones(); ++i) {
    const Bone &x = a.skeleton.bones[i], &y = b.skeleton.bones[i];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.parent, y.parent);
    EXPECT_LE((x.head - y.head).norm(), 1e-9);
    EXPECT_LE((x.tail - y.tail).norm(), 1e-9);
    EXPECT_LE((x.rest - y.rest).cwiseAbs().maxCoeff(), 1e-9) << x.name;
  }
  ASSERT_EQ(b.weights.numVertices(), a.weights.numVertices());
  ASSERT_EQ(b.weights.influences(), a.weights.influences());
  EXPECT_TRUE((b.weights.joints.array() == a.weights.joints.array()).all());
  EXPECT_LE((b.weights.weights - a.weights.weights).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(ObjSkeleton, PolygonsNegativeIndicesAndFaceFormats) {
  const std::string obj = tempPath("quad.obj"), skel = tempPath("quad.json");
  writeText(obj,
            "# tetra-ish: a quad fan plus triangles\r\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\n"
            "vt 0 0\nvn 0 0 1\ng body\nusemtl x\n"
            "f 4/1/1 3/1/1 2/1/1 1/1/1\nf 1//1 2//1 5//1\nf -4/1 -3/1 -1/1\nf 3 4 5\nf -2 -5 -1\n");
  writeText(skel,
            R"({"bones":[{"name":"child","parent":"base","head":[0,0,1],"tail":[0,0,2]},
                         {"name":"base","parent":null,"head":[0,0,0],"tail":[0,0,1],"x_axis":[1,0,0]}],
                "weights":{"base":[[0,1.0],[1,0.5]],"child":[[1,0.5],[4,2.0]]}})");
  const Character c = loadObjWithSkeleton(obj, skel);
  EXPECT_EQ(c.mesh.numVertices(), 5);
  EXPECT_EQ(c.mesh.numTriangles(), 6);
  const TopologyReport t = analyzeTopology(c.mesh);
  EXPECT_TRUE(t.closed());
  EXPECT_TRUE(t.oriented());
  EXPECT_EQ(c.mesh.triangles(0, 0), 3);
  EXPECT_EQ(c.mesh.triangles.row(3), Eigen::RowVector3i(1, 2, 4));  // "f -4/1 -3/1 -1/1" after five vertices
  ASSERT_EQ(c.skeleton.numBones(), 2);
  EXPECT_EQ(c.skeleton.bones[0].name, "base");  // reordered parent-first
  EXPECT_EQ(c.skeleton.bones[1].parent, 0);
  EXPECT_LT((c.skeleton.bones[0].rest.block<3, 1>(0, 0) - Vec3::UnitX()).norm(), 1e-12);
  expectBoneFrames(c.skeleton);
  EXPECT_EQ(c.weights.joints(4, 0), 1);
  EXPECT_DOUBLE_EQ(c.weights.weights(4, 0), 1.0);  // normalised
  EXPECT_EQ(c.weights.joints(2, 0), -1);           // no weights
}

// ============================================================================
// Bad inputs
// ============================================================================

TEST(BadInput, MissingFile) {
  const std::string missing = tempPath("does_not_exist.glb");
  const std::string msg = inputErrorOf([&] { loadCharacter(missing); });
  EXPECT_NE(msg.find("does_not_exist.glb"), std::string::npos) << msg;
  EXPECT_FALSE(inputErrorOf([&] { loadObjWithSkeleton(tempPath("nope.obj"), tempPath("nope.json")); }).empty());
}

TEST(BadInput, TextRenamedGlb) {
  const std::string path = tempPath("text.glb");
  writeText(path, "this is not a glTF file\n");
  const std::string msg = inputErrorOf([&] { loadGltf(path); });
  EXPECT_NE(msg.find("text.glb"), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  const std::string gltf = tempPath("text.gltf");
  writeText(gltf, "{ not json");
  EXPECT_FALSE(inputErrorOf([&] { loadCharacter(gltf); }).empty());
}

TEST(BadInput, ObjWithNanVertex) {
  const std::string obj = tempPath("nan.obj"), skel = tempPath("nan.json");
  writeText(obj, "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n");
  writeText(skel, R"({"bones":[{"name":"b","parent":null,"head":[0,0,0],"tail":[0,1,0]}]})");
  const std::string msg = inputErrorOf([&] { loadObjWithSkeleton(obj, skel); });
  EXPECT_NE(msg.find("nan.obj"), std::string::npos) << msg;
}

TEST(BadInput, ObjFaceIndexOutOfRange) {
  const std::string obj = tempPath("range.obj"), skel = tempPath("range.json");
  writeText(skel, R"({"bones":[{"name":"b","parent":null,"head":[0,0,0],"tail":[0,1,0]}]})");
  writeText(obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
  EXPECT_NE(inputErrorOf([&] { loadObjWithSkeleton(obj, skel); }).find("out of range"), std::string::npos);
  writeText(obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n");
  EXPECT_FALSE(inputErrorOf([&] { loadObjWithSkeleton(obj, skel); }).empty());
  writeText(obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n");
  EXPECT_FALSE(inputErrorOf([&] { loadObjWithSkeleton(obj, skel); }).empty());
}

TEST(BadInput, SkeletonWithZeroLengthBone) {
  const std::string obj = tempPath("zero.obj"), skel = tempPath("zero.json");
  writeText(obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  writeText(skel, R"({"bones":[{"name":"root","parent":null,"head":[0,0,0],"tail":[0,1,0]},
                               {"name":"flat","parent":"root","head":[0,1,0],"tail":[0,1,0]}]})");
  const std::string msg = inputErrorOf([&] { loadObjWithSkeleton(obj, skel); });
  EXPECT_NE(msg.find("flat"), std::string::npos) << msg;
}

TEST(BadInput, SkeletonJsonProblems) {
  const std::string obj = tempPath("skel.obj"), skel = tempPath("skel.json");
  writeText(obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const char* bad[] = {
      "not json",
      R"({"bones":[]})",
      R"({"bones":[{"name":"a","parent":"ghost","head":[0,0,0],"tail":[0,1,0]}]})",
      R"({"bones":[{"name":"a","parent":"b","head":[0,0,0],"tail":[0,1,0]},
                   {"name":"b","parent":"a","head":[0,0,0],"tail":[0,1,0]}]})",
      R"({"bones":[{"name":"a","parent":null,"head":[0,0,0],"tail":[0,1,0]}],"weights":{"a":[[7,1.0]]}})",
      R"({"bones":[{"name":"a","parent":null,"head":[0,0,0],"tail":[0,1,0]}],"weights":{"a":[[0,-1.0]]}})",
      R"({"bones":[{"name":"a","parent":null,"head":[0,0],"tail":[0,1,0]}]})",
  };
  for (const char* text : bad) {
    writeText(skel, text);
    EXPECT_FALSE(inputErrorOf([&] { loadObjWithSkeleton(obj, skel); }).empty()) << text;
  }
  // requireWeights without weights.
  writeText(skel, R"({"bones":[{"name":"a","parent":null,"head":[0,0,0],"tail":[0,1,0]}]})");
  LoadOptions options;
  options.requireWeights = true;
  EXPECT_FALSE(inputErrorOf([&] { loadObjWithSkeleton(obj, skel, options); }).empty());
  EXPECT_NO_THROW(loadObjWithSkeleton(obj, skel));
}

TEST(BadInput, UnknownExtensionAndMissingSkeleton) {
  const std::string path = tempPath("character.fbx");
  writeText(path, "whatever");
  const std::string msg = inputErrorOf([&] { loadCharacter(path); });
  EXPECT_NE(msg.find(".fbx"), std::string::npos) << msg;
  const std::string obj = tempPath("lonely.obj");
  writeText(obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_NE(inputErrorOf([&] { loadCharacter(obj); }).find("skeleton"), std::string::npos);
}
