// libFuzzer target: the section stage on one polygon: triangulateSection (with forced diagonals), findBumps,
// fitBumpEllipse. Input: a header byte (bit 0: coordinates as raw doubles, else int16 pairs on a grid whose
// scale is 10^(byte 1 % 12 - 8) metres; bits 1-3: base harmonics; bit 4: no junction absorption; bit 5: force the mirror-axis diagonal too), two
// diagonal index pairs (4 bytes; 255 first = none), then the coordinates. Accepted polygons must give finite ellipses.
#include "fuzz_support.h"
#include "myoskin/bumps.h"

using namespace myoskin;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  fuzz::Reader in(data, size);
  const uint8_t mode = in.take<uint8_t>();
  const double scale = std::pow(10.0, in.take<uint8_t>() % 12 - 8);
  std::array<uint8_t, 4> d{};
  for (uint8_t& x : d) x = in.take<uint8_t>();
  std::vector<Vec2> points;
  while (in.remaining() > 0 && points.size() < 400) {
    if (mode & 1) {
      const double x = in.take<double>();
      const double y = in.take<double>();
      points.emplace_back(x, y);
    } else {
      const int16_t x = in.take<int16_t>();
      const int16_t y = in.take<int16_t>();
      points.emplace_back(x * scale, y * scale);
    }
  }
  Points2 polygon(static_cast<Eigen::Index>(points.size()), 2);
  for (size_t i = 0; i < points.size(); ++i) polygon.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
  const int n = std::max<int>(1, static_cast<int>(points.size()));
  std::vector<std::array<int, 2>> diagonals;
  if (d[0] != 255) diagonals.push_back({d[0] % n, d[1] % n});
  if (d[2] != 255) diagonals.push_back({d[2] % n - 1, d[3] % n});  // -1: an index outside the polygon
  if (mode & 32) diagonals.push_back(axisDiagonal(polygon));
  BumpOptions options;
  options.baseHarmonics = (mode >> 1) & 7;
  options.absorbJunctions = !(mode & 16);
  fuzz::expectInputErrorOnly([&] {
    const SectionTriangulation t = triangulateSection(polygon, diagonals);
    if (t.kinds.size() != static_cast<size_t>(t.triangles.rows())) fuzz::fail("one kind per triangle");
    if (t.triangles.size() > 0 && (t.triangles.minCoeff() < 0 || t.triangles.maxCoeff() >= polygon.rows()))
      fuzz::fail("triangle index outside the polygon");
    for (const Bump& b : findBumps(polygon, options, &t)) {
      if (b.first < 0 || b.first >= polygon.rows() || b.last < 0 || b.last >= polygon.rows() || b.apex < 0 ||
          b.apex >= polygon.rows())
        fuzz::fail("bump index outside the polygon");
      if (!std::isfinite(b.protrusion) || !std::isfinite(b.significance)) fuzz::fail("bump measure not finite");
      const Ellipse2 e = fitBumpEllipse(polygon, b, t);
      if (!e.center.allFinite() || !std::isfinite(e.a) || !std::isfinite(e.b) || !std::isfinite(e.angle))
        fuzz::fail("ellipse not finite");
    }
  });
  return 0;
}
