// The per-frame skin solve against the muscles (skin_solve.h): rest pose exact, no skin vertex inside a posed muscle
// over an animation (checked independently with CGAL's ray-shooting containment), sliding over the biceps on elbow
// flexion, regions, determinism, bad input.
#include <gtest/gtest.h>

#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>

#include <cmath>
#include <cstdio>
#include <memory>

#include "test_support.h"
#include "myoskin/character.h"
#include "myoskin/errors.h"
#include "myoskin/extraction.h"
#include "myoskin/io.h"
#include "myoskin/pose_io.h"
#include "myoskin/secondary_motion.h"
#include "myoskin/skin_solve.h"
#include "myoskin/skinning.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

namespace {


using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<K::Point_3>;
using Primitive = CGAL::AABB_face_graph_triangle_primitive<SurfaceMesh>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

// One posed muscle surface as CGAL sees it: containment by ray shooting and distances, independent of the solver.
struct CgalMuscle {
  SurfaceMesh mesh;
  std::unique_ptr<Tree> tree;
  std::unique_ptr<CGAL::Side_of_triangle_mesh<SurfaceMesh, K>> side;
  Eigen::AlignedBox3d box;

  CgalMuscle(const Points& v, const Triangles& f) {
    std::vector<SurfaceMesh::Vertex_index> vi;
    for (Eigen::Index i = 0; i < v.rows(); ++i) {
      vi.push_back(mesh.add_vertex(K::Point_3(v(i, 0), v(i, 1), v(i, 2))));
      box.extend(Vec3(v.row(i).transpose()));
    }
    for (Eigen::Index i = 0; i < f.rows(); ++i) mesh.add_face(vi[f(i, 0)], vi[f(i, 1)], vi[f(i, 2)]);
    tree = std::make_unique<Tree>(faces(mesh).first, faces(mesh).second, mesh);
    tree->accelerate_distance_queries();
    side = std::make_unique<CGAL::Side_of_triangle_mesh<SurfaceMesh, K>>(*tree);
  }
  // Depth inside (> 0) or 0 when outside or on the surface.
  double depth(const Vec3& p) const {
    if (!box.contains(p)) return 0.0;
    const K::Point_3 q(p.x(), p.y(), p.z());
    if ((*side)(q) != CGAL::ON_BOUNDED_SIDE) return 0.0;
    return std::sqrt(tree->squared_distance(q));
  }
};

// `bone` and its subtree turned about its posed head by `degrees`, about the world axis perpendicular to the
// `hinge` bone and to `facing` (forward flexion; negative degrees bend backwards), on top of `pose`.
void bend(const Skeleton& sk, Pose& pose, const std::string& bone, const std::string& hinge, double degrees,
          const Vec3& facing = Vec3::UnitZ()) {
  const int b = sk.find(bone), h = sk.find(hinge);
  ASSERT_GE(b, 0) << bone;
  ASSERT_GE(h, 0) << hinge;
  const Vec3 d = (sk.bones[h].tail - sk.bones[h].head).normalized();
  const Vec3 axis = d.cross(facing).normalized();
  const Vec3 joint = pose.matrices[b].block<3, 1>(0, 3);
  Mat4 m = Mat4::Identity();
  m.block<3, 3>(0, 0) = Eigen::AngleAxisd(degrees * kPi / 180.0, axis).toRotationMatrix();
  m.block<3, 1>(0, 3) = joint - m.block<3, 3>(0, 0) * joint;
  std::vector<char> moved(sk.numBones(), 0);
  for (int i = 0; i < sk.numBones(); ++i) {
    moved[i] = i == b || (sk.bones[i].parent >= 0 && moved[sk.bones[i].parent]);
    if (moved[i]) pose.matrices[i] = m * pose.matrices[i];
  }
}

// A character with its extracted muscles, the rig, the hybrid weights and both skinners (hybrid and plain LBS).
struct Rigged {
  Character character;
  std::unique_ptr<MuscleRig> rig;
  SkinWeights combined;
  std::unique_ptr<Skinner> hybrid, lbs;
  double size = 0.0;  // principal extent

  explicit Rigged(Character c, std::vector<Muscle> muscles) : character(std::move(c)) {
    rig = std::make_unique<MuscleRig>(character.skeleton, muscles);
    combined = computeHybridWeights(character.mesh, character.weights, *rig);
    const int nb = character.skeleton.numBones();
    hybrid = std::make_unique<Skinner>(character.mesh.vertices, combined, nb + rig->numJoints());
    lbs = std::make_unique<Skinner>(character.mesh.vertices, character.weights, nb);
    size = principalExtent(character.mesh.vertices);
  }
  // The hybrid (or, plain, skeleton-only) skin at a pose; the rig state evaluated with surfaces.
  Points goal(const Pose& pose, MuscleRigState& state, bool plain = false) const {
    rig->evaluate(pose, state, true);
    std::vector<Mat4> t;
    Points out;
    if (plain) {
      skeletonTransforms(character.skeleton, pose, t);
      lbs->deform(t, out);
    } else {
      skinningTransforms(character.skeleton, pose, *rig, state, t);
      hybrid->deform(t, out);
    }
    return out;
  }
};

const Rigged* makehuman() {
  static std::unique_ptr<Rigged> s = [] {
    const std::string path = test::sharedPath("characters/makehuman_muscular_male/makehuman_muscular_male.glb");
    if (!test::exists(path)) return std::unique_ptr<Rigged>();
    Character c = loadCharacter(path);
    std::vector<Muscle> muscles = extractMuscles(c).muscles;
    return std::make_unique<Rigged>(std::move(c), std::move(muscles));
  }();
  return s.get();
}

const Rigged& arm() {
  static const Rigged s = [] {
    SyntheticArmOptions o;
    o.ringsPerMetre = 200;
    o.segmentsAround = 64;
    Character c = makeSyntheticArm(o).character;
    std::vector<Muscle> muscles = extractMuscles(c).muscles;
    return Rigged(std::move(c), std::move(muscles));
  }();
  return s;
}

#define REQUIRE_MAKEHUMAN()                                                                                   \
  const Rigged* mh = makehuman();                                                                             \
  if (!mh) GTEST_SKIP() << "needs characters/makehuman_muscular_male (the ../shared folder beside the repository)"

// The test animation on MakeHuman: both elbows and knees flexing together, t in (0, 1].
Pose animationPose(const Skeleton& sk, double t) {
  Pose pose = restPose(sk);
  for (const char* side : {".L", ".R"}) {
    const std::string s = side;
    bend(sk, pose, "lowerarm01" + s, "upperarm02" + s, 130.0 * t);
    bend(sk, pose, "lowerleg01" + s, "upperleg02" + s, -120.0 * t);
    bend(sk, pose, "upperarm01" + s, "upperarm01" + s, 40.0 * t);  // shoulder flexion
  }
  return pose;
}

}  // namespace

// ============================================================================
// Rest pose
// ============================================================================

TEST(SkinSolve, RestPoseReturnsTheSkinExactly) {
  for (int which = 0; which < 2; ++which) {
    const Rigged* s = which == 0 ? &arm() : makehuman();
    if (!s) continue;
    ASSERT_GT(s->rig->numMuscles(), 0);
    SkinSolver solver(s->character.mesh, *s->rig,
                      defaultGoalWeights(s->combined, s->character.skeleton.numBones()));
    ASSERT_GT(solver.report().slidingVertices, 0);
    MuscleRigState state = s->rig->makeState();
    const Points goal = s->goal(restPose(s->character.skeleton), state);
    Points out;
    solver.solve(goal, state, out);
    const double err = (out - s->character.mesh.vertices).cwiseAbs().maxCoeff();
    std::printf("%s: rest pose error %.2e m (%.2e of the size); %d vertices inside a muscle at rest (deepest %.2f "
                "mm), %d regions, %d sliding vertices\n",
                which == 0 ? "synthetic arm" : "makehuman_muscular_male", err, err / s->size,
                solver.report().insideAtRest, 1e3 * solver.report().maxRestDepth, solver.report().regions,
                solver.report().slidingVertices);
    EXPECT_LE(err, 1e-6 * s->size);
    // A float64 goal at rest: only the springs' rounding.
    solver.solve(s->character.mesh.vertices, state, out);
    const double err64 = (out - s->character.mesh.vertices).cwiseAbs().maxCoeff();
    std::printf("  from the float64 rest skin: %.2e of the size\n", err64 / s->size);
    EXPECT_LE(err64, 1e-12 * s->size);
  }
}

// ============================================================================
// No penetration over an animation
// ============================================================================

TEST(SkinSolve, NoSkinVertexGoesIntoAMuscleOverAnAnimation) {
  REQUIRE_MAKEHUMAN();
  const Rigged& s = *mh;
  SkinSolver solver(s.character.mesh, *s.rig, defaultGoalWeights(s.combined, s.character.skeleton.numBones()));
  const Eigen::VectorXd& restDepth = solver.restDepth();
  MuscleRigState state = s.rig->makeState();
  const int nm = s.rig->numMuscles();
  ASSERT_GE(nm, 10);
  int goalInside = 0, checkedFrames = 0;
  for (bool plain : {false, true}) {  // the hybrid skin as goal, and plain LBS (where muscles poke out more)
    for (double t : {0.25, 0.5, 0.75, 1.0}) {
      const Pose pose = animationPose(s.character.skeleton, t);
      const Points goal = s.goal(pose, state, plain);
      Points out;
      solver.solve(goal, state, out);
      std::vector<std::unique_ptr<CgalMuscle>> cgal;
      for (int m = 0; m < nm; ++m)
        cgal.push_back(std::make_unique<CgalMuscle>(state.surfaces[m], s.rig->restSurface(m).triangles));
      int inside = 0, deeper = 0, before = 0;
      double worst = 0.0;
      for (int v = 0; v < s.character.mesh.numVertices(); ++v) {
        double d = 0.0, dg = 0.0;
        for (int m = 0; m < nm; ++m) {
          d = std::max(d, cgal[m]->depth(out.row(v).transpose()));
          dg = std::max(dg, cgal[m]->depth(goal.row(v).transpose()));
        }
        before += dg > restDepth[v] + 1e-6 * s.size;
        if (restDepth[v] == 0.0) inside += d > 0.0;
        if (d > restDepth[v] + 1e-6 * s.size) {
          ++deeper, worst = std::max(worst, d - restDepth[v]);
        }
      }
      std::printf("%s t=%.2f: goal vertices deeper in a muscle than at rest %d; after the solve %d (outside at rest "
                  "and now inside: %d, worst %.2e m)\n",
                  plain ? "LBS goal   " : "hybrid goal", t, before, deeper, inside, worst);
      EXPECT_EQ(inside, 0) << "t " << t;
      EXPECT_EQ(deeper, 0) << "t " << t;
      goalInside += before;
      ++checkedFrames;
    }
  }
  EXPECT_EQ(checkedFrames, 8);
  EXPECT_GT(goalInside, 0) << "the animation never pushed skin into a muscle: the test would not see a failure";
}

// ============================================================================
// Sliding
// ============================================================================

TEST(SkinSolve, SkinSlidesOverTheBicepsOnElbowFlexion) {
  REQUIRE_MAKEHUMAN();
  const Rigged& s = *mh;
  int biceps = -1;
  for (int m = 0; m < s.rig->numMuscles(); ++m)
    if (s.rig->muscles()[m].name == "biceps.L") biceps = m;
  ASSERT_GE(biceps, 0) << "no biceps.L among the extracted muscles";
  const int nb = s.character.skeleton.numBones();
  const int j0 = nb + s.rig->jointOffset(biceps), j1 = j0 + s.rig->jointCount(biceps);
  // Skin over the biceps: at least a quarter of its weight on the biceps' joints.
  std::vector<int> over;
  for (int v = 0; v < s.combined.numVertices(); ++v) {
    double w = 0.0, total = 0.0;
    for (int k = 0; k < s.combined.influences(); ++k) {
      const int j = s.combined.joints(v, k);
      if (j < 0) continue;
      total += s.combined.weights(v, k);
      if (j >= j0 && j < j1) w += s.combined.weights(v, k);
    }
    if (total > 0 && w / total >= 0.25) over.push_back(v);
  }
  ASSERT_GE(over.size(), 20u);
  SkinSolver solver(s.character.mesh, *s.rig, defaultGoalWeights(s.combined, nb));
  // Control: goal weight 1 everywhere (no sliding; only the push-out moves the skin).
  SkinSolver held(s.character.mesh, *s.rig, Eigen::VectorXd::Ones(s.character.mesh.numVertices()));
  const double edge = solver.report().meanEdgeLength;
  MuscleRigState state = s.rig->makeState();
  double radius = 0.0;
  for (const MuscleSection& sec : s.rig->muscles()[biceps].sections) radius += std::sqrt(sec.a * sec.b);
  radius /= s.rig->muscles()[biceps].sections.size();
  for (double degrees : {60.0, 120.0}) {
    Pose pose = restPose(s.character.skeleton);
    bend(s.character.skeleton, pose, "lowerarm01.L", "upperarm02.L", degrees);
    const Points goal = s.goal(pose, state);
    const Points normals = vertexNormals(goal, s.character.mesh.triangles);
    // Mean tangential and normal parts of (solved - goal) against the goal surface's normals; largest move.
    auto measure = [&](SkinSolver& sv, double& tangential, double& normal, double& maxMove) {
      Points out;
      sv.solve(goal, state, out);
      tangential = normal = maxMove = 0.0;
      for (int v : over) {
        const Vec3 d = (out.row(v) - goal.row(v)).transpose();
        const Vec3 n = normals.row(v).transpose();
        const double dn = d.dot(n);
        tangential += (d - dn * n).norm() / over.size();
        normal += std::abs(dn) / over.size();
        maxMove = std::max(maxMove, d.norm());
      }
    };
    double tangential, normal, maxMove, heldTangential, heldNormal, heldMax;
    measure(solver, tangential, normal, maxMove);
    measure(held, heldTangential, heldNormal, heldMax);
    std::printf("elbow %.0f deg, %zu vertices over biceps.L: tangential slide mean %.2f mm (%.2f edge lengths; goal "
                "weight 1: %.2f mm); normal move mean %.2f mm (goal weight 1: %.2f mm); largest move %.2f mm (%.2f "
                "biceps radii)\n",
                degrees, over.size(), 1e3 * tangential, tangential / edge, 1e3 * heldTangential, 1e3 * normal,
                1e3 * heldNormal, 1e3 * maxMove, maxMove / radius);
    EXPECT_GT(tangential, 0.15 * edge) << "the skin did not slide";
    EXPECT_GT(tangential, 2.0 * heldTangential) << "the sliding does not come from the goal weights";
    EXPECT_LT(maxMove, radius) << "a vertex moved more than the biceps' radius";
  }
}

// ============================================================================
// Regions, determinism, no drift
// ============================================================================

TEST(SkinSolve, RegionsThatCannotTouchAreSolvedApart) {
  REQUIRE_MAKEHUMAN();
  const Rigged& s = *mh;
  SkinSolver solver(s.character.mesh, *s.rig, defaultGoalWeights(s.combined, s.character.skeleton.numBones()));
  const SkinSolveReport& r = solver.report();
  ASSERT_GE(r.regions, 3) << "arms and legs should be separate regions";
  ASSERT_EQ(static_cast<int>(r.regionMuscles.size()), r.regions);
  // Muscles of the right arm and of the left leg never share a region, nor those of the two legs.
  for (int i = 0; i < r.regions; ++i) {
    bool rightArm = false, leftLeg = false, rightLeg = false;
    std::string names;
    for (int m : r.regionMuscles[i]) {
      const Muscle& mu = s.rig->muscles()[m];
      names += mu.name + " (" + mu.region + ") ";
      const bool arm = mu.region.find("arm") != std::string::npos, leg = mu.region.find("leg") != std::string::npos;
      const bool left = mu.region.size() > 2 && mu.region.compare(mu.region.size() - 2, 2, ".L") == 0;
      rightArm |= arm && !left;
      leftLeg |= leg && left;
      rightLeg |= leg && !left;
    }
    std::printf("region %d: %d vertices, muscles %s\n", i, r.regionSize[i], names.c_str());
    EXPECT_FALSE(rightArm && leftLeg) << "region " << i;
    EXPECT_FALSE(leftLeg && rightLeg) << "region " << i;
    EXPECT_LT(r.regionMuscles[i].size(), static_cast<size_t>(s.rig->numMuscles())) << "region " << i;
  }
}

TEST(SkinSolve, DeterministicAndNothingCarriedBetweenFrames) {
  const Rigged& s = arm();
  SkinSolver solver(s.character.mesh, *s.rig, defaultGoalWeights(s.combined, s.character.skeleton.numBones()));
  MuscleRigState state = s.rig->makeState();
  Pose a = restPose(s.character.skeleton), b = a;
  bend(s.character.skeleton, a, "forearm", "upper_arm", 100.0);
  bend(s.character.skeleton, b, "forearm", "upper_arm", 40.0);
  Points first, other, again;
  const Points goalA = s.goal(a, state);
  solver.solve(goalA, state, first);
  const Points goalB = s.goal(b, state);
  solver.solve(goalB, state, other);
  const Points goalA2 = s.goal(a, state);
  solver.solve(goalA2, state, again);
  EXPECT_GT((first - goalA).cwiseAbs().maxCoeff(), 0.0) << "the solve changed nothing";
  EXPECT_EQ((first - again).cwiseAbs().maxCoeff(), 0.0);
  // Float32 goal (the skinner's output) gives the same as its float64 copy.
  PointsF goalF = goalA.cast<float>();
  Points fromF, fromD;
  solver.solve(goalF, state, fromF);
  s.rig->evaluate(a, state, true);
  solver.solve(Points(goalF.cast<double>()), state, fromD);
  EXPECT_EQ((fromF - fromD).cwiseAbs().maxCoeff(), 0.0);
  // In place on float32 (Simulation's skin-solve hook): the same skin, rounded to float.
  PointsF inPlace = goalF;
  solver.solveInPlace(inPlace, state);
  EXPECT_EQ((inPlace - fromF.cast<float>()).cwiseAbs().maxCoeff(), 0.0f);
  EXPECT_GT((inPlace - goalF).cwiseAbs().maxCoeff(), 0.0f);
}

TEST(SkinSolve, PlugsIntoTheSimulationsSkinSolveHook) {
  // The simulation (jiggle on, filter on) with the solve as its hook: every frame's raw skin is the solve of the
  // (jiggled) skinned frame against the (jiggled) posed muscles, and no vertex outside at rest ends inside one.
  const Rigged& s = arm();
  SkinSolver solver(s.character.mesh, *s.rig, defaultGoalWeights(s.combined, s.character.skeleton.numBones()));
  PoseSequence poses;
  poses.startFrame = 1;
  for (double degrees : {0.0, 40.0, 80.0, 110.0}) {
    Pose pose = restPose(s.character.skeleton);
    bend(s.character.skeleton, pose, "forearm", "upper_arm", degrees);
    poses.frames.push_back(pose);
  }
  SimulationOptions o;
  o.jiggle = true;
  o.filter = true;
  auto skinner = std::make_shared<Skinner>(s.character.mesh.vertices, s.combined,
                                           s.character.skeleton.numBones() + s.rig->numJoints());
  Simulation sim(s.character.mesh, s.character.skeleton, s.rig.get(), skinner, poses, o);
  int calls = 0, changed = 0;
  std::vector<Points> surfaces;  // the posed (jiggled) muscles the hook saw, per frame
  sim.setSkinSolve([&](int frame, const Pose&, const MuscleRigState* rig, PointsF& skin) {
    ASSERT_NE(rig, nullptr);
    const PointsF before = skin;
    solver.solveInPlace(skin, *rig);
    ++calls;
    changed += (skin - before).cwiseAbs().maxCoeff() > 0.0f;
    if (frame == 4) surfaces = rig->surfaces;
  });
  PointsF raw;
  sim.rawFrame(4, raw);
  EXPECT_GT(calls, 0);
  EXPECT_GT(changed, 0) << "the solve never changed a frame";
  ASSERT_EQ(static_cast<int>(surfaces.size()), s.rig->numMuscles());
  int inside = 0;
  for (int m = 0; m < s.rig->numMuscles(); ++m) {
    const CgalMuscle c(surfaces[m], s.rig->restSurface(m).triangles);
    for (int v = 0; v < raw.rows(); ++v)
      inside += c.depth(raw.row(v).transpose().cast<double>()) > solver.restDepth()[v] + 1e-6 * s.size;
  }
  EXPECT_EQ(inside, 0);
}

// ============================================================================
// Muscles poking out of the skin at rest; overlapping muscles
// ============================================================================

TEST(SkinSolve, MusclePokingOutAtRestKeepsTheRestSkinAndGoesNoDeeper) {
  const Rigged& s = arm();
  std::vector<Muscle> muscles = s.rig->muscles();
  ASSERT_FALSE(muscles.empty());
  // Blow the first muscle's surface up about its centre line until it pokes out of the skin.
  for (size_t m = 0; m < muscles.size(); ++m) {
    Mesh surface = s.rig->restSurface(static_cast<int>(m));
    if (m == 0) {
      const Vec3 c = surface.vertices.colwise().mean().transpose();
      for (Eigen::Index i = 0; i < surface.vertices.rows(); ++i)
        surface.vertices.row(i) = (c + 1.6 * (surface.vertices.row(i).transpose() - c)).transpose();
    }
    muscles[m].surface = surface;
  }
  const MuscleRig rig(s.character.skeleton, muscles);
  SkinSolver solver(s.character.mesh, rig, defaultGoalWeights(s.combined, s.character.skeleton.numBones()));
  ASSERT_GT(solver.report().insideAtRest, 0) << "the blown-up muscle does not poke out";
  MuscleRigState state = rig.makeState();
  rig.evaluate(restPose(s.character.skeleton), state, true);
  Points out;
  solver.solve(s.character.mesh.vertices, state, out);
  EXPECT_LE((out - s.character.mesh.vertices).cwiseAbs().maxCoeff(), 1e-6 * s.size);
  Pose pose = restPose(s.character.skeleton);
  bend(s.character.skeleton, pose, "forearm", "upper_arm", 90.0);
  std::vector<Mat4> t;
  rig.evaluate(pose, state, true);
  skeletonTransforms(s.character.skeleton, pose, t);
  Points goal;
  s.lbs->deform(t, goal);
  solver.solve(goal, state, out);
  const CgalMuscle big(state.surfaces[0], rig.restSurface(0).triangles);
  int deeper = 0;
  for (int v = 0; v < out.rows(); ++v)
    deeper += big.depth(out.row(v).transpose()) > solver.restDepth()[v] + 1e-6 * s.size;
  EXPECT_EQ(deeper, 0);
}

TEST(SkinSolve, OverlappingMusclesAreAUnion) {
  const Rigged& s = arm();
  std::vector<Muscle> muscles = s.rig->muscles();
  ASSERT_FALSE(muscles.empty());
  for (size_t m = 0; m < muscles.size(); ++m) muscles[m].surface = s.rig->restSurface(static_cast<int>(m));
  // A copy of the first muscle, shifted by half its radius: the two intersect at rest.
  Muscle copy = muscles[0];
  copy.name += "_copy";
  const double r = std::sqrt(copy.sections[copy.sections.size() / 2].a * copy.sections[copy.sections.size() / 2].b);
  const Vec3 shift = 0.5 * r * copy.sections[copy.sections.size() / 2].axisA;
  for (Eigen::Index i = 0; i < copy.surface.vertices.rows(); ++i) copy.surface.vertices.row(i) += shift.transpose();
  muscles.push_back(copy);
  const MuscleRig rig(s.character.skeleton, muscles);
  SkinWeights combined = computeHybridWeights(s.character.mesh, s.character.weights, rig);
  SkinSolver solver(s.character.mesh, rig, defaultGoalWeights(combined, s.character.skeleton.numBones()));
  const auto& pairs = solver.report().overlappingMuscles;
  ASSERT_NE(std::find(pairs.begin(), pairs.end(), std::make_pair(0, rig.numMuscles() - 1)), pairs.end());
  MuscleRigState state = rig.makeState();
  Pose pose = restPose(s.character.skeleton);
  bend(s.character.skeleton, pose, "forearm", "upper_arm", 110.0);
  rig.evaluate(pose, state, true);
  std::vector<Mat4> t;
  skeletonTransforms(s.character.skeleton, pose, t);
  Points goal, out;
  s.lbs->deform(t, goal);
  solver.solve(goal, state, out);
  ASSERT_TRUE(out.allFinite());
  int inside = 0;
  for (int m = 0; m < rig.numMuscles(); ++m) {
    const CgalMuscle c(state.surfaces[m], rig.restSurface(m).triangles);
    for (int v = 0; v < out.rows(); ++v)
      inside += c.depth(out.row(v).transpose()) > solver.restDepth()[v] + 1e-6 * s.size;
  }
  EXPECT_EQ(inside, 0);
}

// ============================================================================
// Bad input
// ============================================================================

TEST(SkinSolve, BadInputIsAnInputError) {
  const Rigged& s = arm();
  const int nb = s.character.skeleton.numBones();
  const Eigen::VectorXd g = defaultGoalWeights(s.combined, nb);
  // An open collision surface.
  std::vector<Muscle> muscles = s.rig->muscles();
  for (size_t m = 0; m < muscles.size(); ++m) muscles[m].surface = s.rig->restSurface(static_cast<int>(m));
  muscles[0].surface.triangles.conservativeResize(muscles[0].surface.triangles.rows() - 1, 3);
  const MuscleRig open(s.character.skeleton, muscles);
  EXPECT_NE(test::inputErrorOf([&] { SkinSolver(s.character.mesh, open, g); }).find("not closed"), std::string::npos);
  // Goal weights: wrong count, out of range, NaN.
  EXPECT_NE(test::inputErrorOf([&] { SkinSolver(s.character.mesh, *s.rig, g.head(3)); }), "");
  Eigen::VectorXd bad = g;
  bad[5] = 1.5;
  EXPECT_NE(test::inputErrorOf([&] { SkinSolver(s.character.mesh, *s.rig, bad); }), "");
  bad[5] = std::nan("");
  EXPECT_NE(test::inputErrorOf([&] { SkinSolver(s.character.mesh, *s.rig, bad); }), "");
  SkinSolveOptions o;
  o.iterations = -1;
  EXPECT_NE(test::inputErrorOf([&] { SkinSolver(s.character.mesh, *s.rig, g, o); }), "");
  EXPECT_NE(test::inputErrorOf([&] { defaultGoalWeights(s.combined, nb, 2.0); }), "");
  // Frames: NaN goal, wrong size, a state without surfaces, a NaN pose (the rig refuses it).
  SkinSolver solver(s.character.mesh, *s.rig, g);
  MuscleRigState state = s.rig->makeState();
  s.rig->evaluate(restPose(s.character.skeleton), state, true);
  Points goal = s.character.mesh.vertices, out;
  goal(7, 1) = std::nan("");
  EXPECT_NE(test::inputErrorOf([&] { solver.solve(goal, state, out); }).find("NaN"), std::string::npos);
  EXPECT_NE(test::inputErrorOf([&] { solver.solve(Points(goal.topRows(10)), state, out); }), "");
  MuscleRigState bare = s.rig->makeState();
  bare.surfaces.clear();
  EXPECT_NE(test::inputErrorOf([&] { solver.solve(s.character.mesh.vertices, bare, out); }), "");
  state.surfaces[0](0, 0) = std::nan("");
  EXPECT_NE(test::inputErrorOf([&] { solver.solve(s.character.mesh.vertices, state, out); }), "");
  Pose nanPose = restPose(s.character.skeleton);
  nanPose.matrices[1](0, 3) = std::nan("");
  EXPECT_NE(test::inputErrorOf([&] { s.rig->evaluate(nanPose, state, true); }), "");
  // After the refused frames the solver still works.
  s.rig->evaluate(restPose(s.character.skeleton), state, true);
  solver.solve(s.character.mesh.vertices, state, out);
  EXPECT_LE((out - s.character.mesh.vertices).cwiseAbs().maxCoeff(), 1e-6 * s.size);
}
