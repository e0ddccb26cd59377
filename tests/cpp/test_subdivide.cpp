// Midpoint subdivision of a character: shape, topology and weights kept.
#include <gtest/gtest.h>

#include "myoskin/errors.h"
#include "myoskin/subdivide.h"
#include "myoskin/synthetic_character.h"

using namespace myoskin;

TEST(Subdivide, KeepsShapeTopologyAndWeights) {
  SyntheticArmOptions o;
  o.ringsPerMetre = 60;
  o.segmentsAround = 24;
  const Character c = makeSyntheticArm(o).character;
  const Character f = subdivideMidpoint(c, 2);
  EXPECT_EQ(f.mesh.numTriangles(), 16 * c.mesh.numTriangles());
  // Euler characteristic of a closed genus-0 surface: V - E + F = 2 with E = 3F/2.
  EXPECT_EQ(f.mesh.numVertices() - 3 * f.mesh.numTriangles() / 2 + f.mesh.numTriangles(), 2);
  const TopologyReport t = analyzeTopology(f.mesh);
  EXPECT_TRUE(t.closed() && t.manifold() && t.oriented());
  EXPECT_NEAR(enclosedVolume(f.mesh.vertices, f.mesh.triangles), enclosedVolume(c.mesh.vertices, c.mesh.triangles), 1e-12);
  EXPECT_TRUE(f.mesh.vertices.topRows(c.mesh.numVertices()) == c.mesh.vertices);
  validateCharacter(f);
  for (int v = 0; v < f.weights.numVertices(); ++v) EXPECT_NEAR(f.weights.weights.row(v).sum(), 1.0, 1e-12) << v;
  EXPECT_EQ(f.sourceVertexCount, f.mesh.numVertices());
}

TEST(Subdivide, DeterministicAndRejectsBadLevels) {
  SyntheticArmOptions o;
  o.ringsPerMetre = 40;
  o.segmentsAround = 12;
  const Character c = makeSyntheticArm(o).character;
  const Character a = subdivideMidpoint(c, 1), b = subdivideMidpoint(c, 1);
  EXPECT_TRUE(a.mesh.vertices == b.mesh.vertices && a.mesh.triangles == b.mesh.triangles);
  EXPECT_TRUE(subdivideMidpoint(c, 0).mesh.vertices == c.mesh.vertices);
  EXPECT_THROW(subdivideMidpoint(c, -1), InputError);
}
