// Plane-mesh intersection: crossing segments per triangle, chained through shared edges into loops.
#include "sections/plane_loops.h"

#include <algorithm>
#include <cstdint>

namespace myoskin::detail {

namespace {

uint64_t edgeKey(int a, int b) {
  const uint64_t lo = static_cast<uint32_t>(std::min(a, b)), hi = static_cast<uint32_t>(std::max(a, b));
  return lo << 32 | hi;
}

}  // namespace

std::vector<PlaneLoop> planeLoops(const Mesh& mesh, const Vec3& origin, const Vec3& normal, std::vector<double>& d) {
  const int nv = mesh.numVertices(), nf = mesh.numTriangles();
  d.resize(nv);
  for (int v = 0; v < nv; ++v) {
    const double s = (mesh.vertices.row(v).transpose() - origin).dot(normal);
    d[v] = s == 0.0 ? 1e-300 : s;  // on the plane counts as above: no triangle crosses at a vertex
  }
  // Crossing triangles: their two crossed edges, as (edge key, segment end) entries.
  struct End {
    uint64_t key;
    int segment;
  };
  std::vector<End> ends;
  std::vector<std::array<uint64_t, 2>> segments;
  for (int f = 0; f < nf; ++f) {
    const int a = mesh.triangles(f, 0), b = mesh.triangles(f, 1), c = mesh.triangles(f, 2);
    const bool pa = d[a] > 0, pb = d[b] > 0, pc = d[c] > 0;
    if (pa == pb && pb == pc) continue;
    std::array<uint64_t, 2> seg;
    int k = 0;
    if (pa != pb) seg[k++] = edgeKey(a, b);
    if (pb != pc) seg[k++] = edgeKey(b, c);
    if (pc != pa) seg[k++] = edgeKey(c, a);
    const int s = static_cast<int>(segments.size());
    segments.push_back(seg);
    ends.push_back({seg[0], s});
    ends.push_back({seg[1], s});
  }
  std::sort(ends.begin(), ends.end(), [](const End& x, const End& y) { return x.key != y.key ? x.key < y.key : x.segment < y.segment; });
  // For each segment end, the other segment on the same edge (-1 at a boundary or a non-manifold edge).
  auto partner = [&](uint64_t key, int segment) {
    auto it = std::lower_bound(ends.begin(), ends.end(), key, [](const End& e, uint64_t k) { return e.key < k; });
    int other = -1, count = 0;
    for (; it != ends.end() && it->key == key; ++it, ++count)
      if (it->segment != segment) other = it->segment;
    return count == 2 ? other : -1;
  };
  auto point = [&](uint64_t key) {
    const int a = static_cast<int>(key >> 32), b = static_cast<int>(key & 0xffffffffu);
    const double t = d[a] / (d[a] - d[b]);
    return Vec3(mesh.vertices.row(a).transpose() + t * (mesh.vertices.row(b) - mesh.vertices.row(a)).transpose());
  };
  std::vector<char> used(segments.size(), 0);
  std::vector<PlaneLoop> loops;
  for (size_t start = 0; start < segments.size(); ++start) {
    if (used[start]) continue;
    // Walk forward from segment `start` through its second end; if that hits a boundary, walk back too.
    std::vector<uint64_t> keys{segments[start][0]};
    used[start] = 1;
    int seg = static_cast<int>(start);
    uint64_t key = segments[start][1];
    bool closed = false;
    for (;;) {
      keys.push_back(key);
      const int next = partner(key, seg);
      if (next < 0) break;
      if (next == static_cast<int>(start)) {
        closed = true;
        keys.pop_back();  // the start edge again
        break;
      }
      if (used[next]) break;
      used[next] = 1;
      key = segments[next][0] == key ? segments[next][1] : segments[next][0];
      seg = next;
    }
    PlaneLoop loop;
    loop.closed = closed;
    for (uint64_t k : keys) {
      loop.points.push_back(point(k));
      loop.edges.push_back({static_cast<int>(k >> 32), static_cast<int>(k & 0xffffffffu)});
    }
    loops.push_back(std::move(loop));
  }
  return loops;
}

}  // namespace myoskin::detail
