#include "frictiond/estimators/span_coverage.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>
#include <utility>

#include "frictiond/estimators/identification_memo.h"

namespace frictiond {

bool SpanRect::IsValid() const {
  return std::isfinite(fn_min_n) && std::isfinite(fn_max_n) &&
         std::isfinite(v_min_mm_s) && std::isfinite(v_max_mm_s) &&
         fn_max_n > fn_min_n && v_max_mm_s > v_min_mm_s;
}

namespace {

using Point = std::pair<double, double>;

double Cross(const Point& o, const Point& a, const Point& b) {
  return (a.first - o.first) * (b.second - o.second) -
         (a.second - o.second) * (b.first - o.first);
}

// An edge of a convex polygon as origin and direction.
struct Edge {
  double x, y, dx, dy;
};

// Strictly left of every edge: strictly inside the polygon.
bool StrictlyInside(const std::vector<Edge>& edges, const Point& q) {
  for (const Edge& g : edges) {
    // Cross(a, b, q) > 0, written out.
    if (!(g.dx * (q.second - g.y) - g.dy * (q.first - g.x) > 0)) return false;
  }
  return !edges.empty();
}

// Akl-Toussaint: the points extreme in x, y, x + y and x - y are on the
// hull; in counter-clockwise order they span a convex polygon, and a point
// strictly inside it is no hull vertex. Returns that polygon's edges (none
// below 64 points, where the test costs more than it saves, or when the
// extremes span no area).
// Directions in counter-clockwise order: min x, min x+y, min y,
// max x-y, max x, max x+y, max y, min x-y (as maxima of 8 keys).
void OctagonKeys(const Point& q, double* k) {
  const double x = q.first, y = q.second;
  k[0] = -x;
  k[1] = -(x + y);
  k[2] = -y;
  k[3] = x - y;
  k[4] = x;
  k[5] = x + y;
  k[6] = y;
  k[7] = y - x;
}

// Folds `q` into the extremes found so far (of equal ones, the first
// stays); `first`: q is the first point.
void FoldExtreme(const Point& q,
                 double* best,
                 std::array<Point, 8>* extremes,
                 bool first) {
  double k[8];
  OctagonKeys(q, k);
  for (int d = 0; d < 8; ++d) {
    if (first || k[d] > best[d]) {
      best[d] = k[d];
      (*extremes)[d] = q;
    }
  }
}

// The convex polygon of the extremes, as edges (none when it spans no
// area).
std::vector<Edge> OctagonEdges(const std::array<Point, 8>& e) {
  std::vector<Point> poly;
  for (int d = 0; d < 8; ++d) {
    if (poly.empty() || poly.back() != e[d]) poly.push_back(e[d]);
  }
  while (poly.size() > 1 && poly.back() == poly.front()) poly.pop_back();
  if (poly.size() < 3) return {};
  std::vector<Edge> edges;
  for (std::size_t j = 0; j < poly.size(); ++j) {
    const Point& a = poly[j];
    const Point& b = poly[j + 1 < poly.size() ? j + 1 : 0];
    edges.push_back(
        {a.first, a.second, b.first - a.first, b.second - a.second});
  }
  return edges;
}

std::vector<Edge> InteriorOctagon(const std::vector<Point>& p) {
  if (p.size() < 64) return {};
  std::array<Point, 8> e;
  double best[8];
  for (std::size_t i = 0; i < p.size(); ++i)
    FoldExtreme(p[i], best, &e, i == 0);
  return OctagonEdges(e);
}

// Drops the points strictly inside InteriorOctagon (no hull vertices):
// the hull is unchanged and, for spread-out data, few points are left to
// sort. The others keep their order.
void DropInteriorPoints(std::vector<Point>* points) {
  const std::vector<Edge> edges = InteriorOctagon(*points);
  if (edges.empty()) return;
  points->erase(std::remove_if(points->begin(),
                               points->end(),
                               [&edges](const Point& q) {
                                 return StrictlyInside(edges, q);
                               }),
                points->end());
}

// All of `p` on one vertical or horizontal line (e.g. a constant load
// clamped to the reference span): true, and the hull (the segment between
// the ends, or the one point) in *hull.
bool AxisSegmentHull(const std::vector<Point>& p, std::vector<Point>* hull) {
  if (!p.empty()) {
    bool same_x = true, same_y = true;
    double y_lo = p[0].second, y_hi = y_lo, x_lo = p[0].first, x_hi = x_lo;
    for (const Point& q : p) {
      same_x = same_x && q.first == p[0].first;
      same_y = same_y && q.second == p[0].second;
      y_lo = std::min(y_lo, q.second);
      y_hi = std::max(y_hi, q.second);
      x_lo = std::min(x_lo, q.first);
      x_hi = std::max(x_hi, q.first);
    }
    if (same_x || same_y) {
      const Point lo =
          same_x ? Point{p[0].first, y_lo} : Point{x_lo, p[0].second};
      const Point hi =
          same_x ? Point{p[0].first, y_hi} : Point{x_hi, p[0].second};
      if (lo == hi) {
        *hull = {lo};
      } else {
        *hull = {lo, hi};
      }
      return true;
    }
  }
  return false;
}

// Andrew's monotone chain on points in lexicographic order (duplicates
// allowed): CalcConvexHull's answer.
std::vector<Point> ChainHull(std::vector<Point> p) {
  p.erase(std::unique(p.begin(), p.end()), p.end());
  const std::size_t n = p.size();
  if (n < 3) return p;
  // Andrew's monotone chain: lower then upper hull.
  std::vector<Point> hull(2 * n);
  std::size_t k = 0;
  for (std::size_t i = 0; i < n; ++i) {
    while (k >= 2 && Cross(hull[k - 2], hull[k - 1], p[i]) <= 0) --k;
    hull[k++] = p[i];
  }
  for (std::size_t i = n - 1, t = k + 1; i-- > 0;) {
    while (k >= t && Cross(hull[k - 2], hull[k - 1], p[i]) <= 0) --k;
    hull[k++] = p[i];
  }
  hull.resize(k - 1);
  return hull;
}

}  // namespace

std::vector<std::pair<double, double>> CalcConvexHull(
    std::vector<std::pair<double, double>> p) {
  std::vector<Point> segment;
  if (AxisSegmentHull(p, &segment)) return segment;
  DropInteriorPoints(&p);
  std::sort(p.begin(), p.end());
  return ChainHull(std::move(p));
}

namespace {

// Shoelace area of a hull polygon (CalcConvexHull's order); 0 below 3
// vertices.
double PolygonArea(const std::vector<Point>& hull) {
  if (hull.size() < 3) return 0.0;
  double twice_area = 0.0;
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const Point& a = hull[i];
    const Point& b = hull[(i + 1) % hull.size()];
    twice_area += a.first * b.second - b.first * a.second;
  }
  return std::fabs(twice_area) / 2.0;
}

}  // namespace

double CalcConvexHullArea(std::vector<std::pair<double, double>> p) {
  return PolygonArea(CalcConvexHull(std::move(p)));
}

namespace {

// p clamped into the reference (branch-free: a non-finite point is
// clamped too, the caller drops it).
Point ClampInto(const SpanRect& r, double fn, double v) {
  return {std::min(std::max(fn, r.fn_min_n), r.fn_max_n),
          std::min(std::max(v, r.v_min_mm_s), r.v_max_mm_s)};
}

// The finite samples grouped by stroke id (ascending) and each stroke's
// hull, looked up in the memo's stroke_hulls when it holds it. With
// `clamp`, the points are clamped into it first (CalcSpanCoverage's
// hulls, keyed apart from CalcMaterialHullCoverage's).
struct StrokeHulls {
  std::vector<int> ids;
  std::vector<int> samples;  // per stroke
  std::vector<std::shared_ptr<const MemoHull>> hulls;
  int total = 0;  // finite samples

  // Two opposite corners of each hull's bounding box: the same extent as
  // all the vertices, and on one axis line exactly when they are.
  std::vector<Point> BoxCorners() const;
};

// A hull's bounding box: its extremes in -x, x, -y and y (four of the
// octagon's directions).
SpanRect BoxOf(const MemoHull& h) {
  return {h.extremes[0].first,
          h.extremes[4].first,
          h.extremes[2].second,
          h.extremes[6].second};
}

std::vector<Point> StrokeHulls::BoxCorners() const {
  std::vector<Point> corners;
  corners.reserve(2 * hulls.size());
  for (const auto& h : hulls) {
    const SpanRect box = BoxOf(*h);
    corners.emplace_back(box.fn_min_n, box.v_min_mm_s);
    corners.emplace_back(box.fn_max_n, box.v_max_mm_s);
  }
  return corners;
}

// The hull of the union of the strokes' hulls: the strict vertices of the
// hull of a union are vertices of the parts' hulls, so it is the hull of
// the parts' vertices. Each part's vertices are in lexicographic order
// (MemoHull), so merging them replaces the sort, and each part's
// extremes and bounding box give the octagon that drops interior points
// (a part whose box is inside it is skipped whole) without a pass over
// every vertex. A smooth stroke's slipping samples often trace a convex
// arc, every one a vertex of its hull. Equal to CalcConvexHull of all the
// parts' vertices.
std::vector<Point> UnionHull(const StrokeHulls& parts) {
  const auto& hulls = parts.hulls;
  if (hulls.empty()) return {};
  std::size_t total = 0;
  for (const auto& h : hulls) total += h->vertices.size();
  // All on one vertical or horizontal line: the boxes' corners give
  // AxisSegmentHull's answer for all the vertices.
  std::vector<Point> segment;
  if (AxisSegmentHull(parts.BoxCorners(), &segment)) return segment;
  std::vector<Edge> edges;
  if (total >= 64) {
    std::array<Point, 8> e;
    double best[8];
    bool first = true;
    for (const auto& h : hulls) {
      for (const Point& q : h->extremes) {
        FoldExtreme(q, best, &e, first);
        first = false;
      }
    }
    edges = OctagonEdges(e);
  }
  // The survivors, one sorted run per part.
  std::vector<Point> a;
  std::vector<std::size_t> ends;
  a.reserve(total);
  for (const auto& h : hulls) {
    const SpanRect box = BoxOf(*h);
    if (!edges.empty() &&
        StrictlyInside(edges, {box.fn_min_n, box.v_min_mm_s}) &&
        StrictlyInside(edges, {box.fn_max_n, box.v_min_mm_s}) &&
        StrictlyInside(edges, {box.fn_min_n, box.v_max_mm_s}) &&
        StrictlyInside(edges, {box.fn_max_n, box.v_max_mm_s}))
      continue;
    for (const Point& q : h->vertices) {
      if (edges.empty() || !StrictlyInside(edges, q)) a.push_back(q);
    }
    ends.push_back(a.size());
  }
  // Bottom-up merge of neighbouring runs.
  std::vector<Point> b(a.size());
  while (ends.size() > 1) {
    std::vector<std::size_t> merged;
    std::size_t begin = 0;
    for (std::size_t r = 0; r < ends.size(); r += 2) {
      const std::size_t mid = ends[r];
      const std::size_t end = r + 1 < ends.size() ? ends[r + 1] : mid;
      std::merge(a.begin() + begin,
                 a.begin() + mid,
                 a.begin() + mid,
                 a.begin() + end,
                 b.begin() + begin);
      merged.push_back(end);
      begin = end;
    }
    a.swap(b);
    ends.swap(merged);
  }
  return ChainHull(std::move(a));
}

// One stroke's hull from its points (clamped first with `clamp`).
MemoHull CalcStrokeHull(std::vector<Point> points, const SpanRect* clamp) {
  if (clamp) {
    for (Point& q : points) q = ClampInto(*clamp, q.first, q.second);
  }
  MemoHull h;
  h.vertices = CalcConvexHull(std::move(points));
  h.area = PolygonArea(h.vertices);
  std::sort(h.vertices.begin(), h.vertices.end());
  const std::vector<Point>& v = h.vertices;  // not empty: >= 1 point
  double best[8];
  for (std::size_t i = 0; i < v.size(); ++i)
    FoldExtreme(v[i], best, &h.extremes, i == 0);
  return h;
}

// One stroke's hull, looked up in the memo (keyed by every input the hull
// reads: the points in order and the clamp rectangle). `point(i)`, i <
// n, is the stroke's i-th point.
template <typename PointAt>
std::shared_ptr<const MemoHull> StrokeHull(IdentificationMemo* memo,
                                           const SpanRect* clamp,
                                           std::size_t n,
                                           const PointAt& point) {
  return Memoized(
      memo ? &memo->stroke_hulls : nullptr,
      n,
      [&] {
        MemoKeyBuilder h(clamp ? 0x5370616e48756c6cULL    // "SpanHull"
                               : 0x5374726f48756c6cULL);  // "StroHull"
        if (clamp) {
          h.Add(clamp->fn_min_n)
              .Add(clamp->fn_max_n)
              .Add(clamp->v_min_mm_s)
              .Add(clamp->v_max_mm_s);
        }
        h.Add(static_cast<std::uint64_t>(n));
        for (std::size_t i = 0; i < n; ++i) {
          const Point q = point(i);
          h.Add(q.first).Add(q.second);
        }
        return h.Key();
      },
      [&] {
        std::vector<Point> points(n);
        for (std::size_t i = 0; i < n; ++i) points[i] = point(i);
        return CalcStrokeHull(std::move(points), clamp);
      });
}

StrokeHulls CollectStrokeHulls(const std::vector<double>& fn_n,
                               const std::vector<double>& v_mm_s,
                               const std::vector<int>& stroke,
                               const SpanRect* clamp,
                               IdentificationMemo* memo) {
  StrokeHulls out;
  const std::size_t n = fn_n.size();
  // A refit's samples: every point finite and the ids never decreasing,
  // so each stroke is one range of the columns, read in place.
  bool ranges = true;
  for (std::size_t i = 0; i < n && ranges; ++i) {
    ranges = std::isfinite(fn_n[i]) && std::isfinite(v_mm_s[i]) &&
             (i == 0 || stroke[i] >= stroke[i - 1]);
  }
  if (ranges) {
    for (std::size_t b = 0, e; b < n; b = e) {
      for (e = b + 1; e < n && stroke[e] == stroke[b];) ++e;
      out.ids.push_back(stroke[b]);
      out.samples.push_back(static_cast<int>(e - b));
      out.hulls.push_back(StrokeHull(memo, clamp, e - b, [&](std::size_t i) {
        return Point{fn_n[b + i], v_mm_s[b + i]};
      }));
    }
    out.total = static_cast<int>(n);
    return out;
  }
  // Otherwise grouped by id (ascending), the finite points only.
  std::map<int, std::vector<Point>> by;
  std::vector<Point>* last = nullptr;  // consecutive samples share a stroke
  int last_id = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!(std::isfinite(fn_n[i]) && std::isfinite(v_mm_s[i]))) continue;
    ++out.total;
    if (last == nullptr || stroke[i] != last_id) {
      last_id = stroke[i];
      last = &by[last_id];
    }
    last->emplace_back(fn_n[i], v_mm_s[i]);
  }
  for (const auto& entry : by) {
    const std::vector<Point>& points = entry.second;
    out.ids.push_back(entry.first);
    out.samples.push_back(static_cast<int>(points.size()));
    out.hulls.push_back(
        StrokeHull(memo, clamp, points.size(), [&points](std::size_t i) {
          return points[i];
        }));
  }
  return out;
}

void Extend(SpanRect* r, double fn, double v) {
  r->fn_min_n = std::min(r->fn_min_n, fn);
  r->fn_max_n = std::max(r->fn_max_n, fn);
  r->v_min_mm_s = std::min(r->v_min_mm_s, v);
  r->v_max_mm_s = std::max(r->v_max_mm_s, v);
}

// The extent of `points` (not empty), two points per step (a single
// running min/max would wait for each comparison before the next).
SpanRect ExtentOf(const std::vector<Point>& points) {
  SpanRect c, c2;
  c = c2 = {
      points[0].first, points[0].first, points[0].second, points[0].second};
  std::size_t i = 0;
  for (; i + 2 <= points.size(); i += 2) {
    Extend(&c, points[i].first, points[i].second);
    Extend(&c2, points[i + 1].first, points[i + 1].second);
  }
  if (i < points.size()) Extend(&c, points[i].first, points[i].second);
  Extend(&c, c2.fn_min_n, c2.v_min_mm_s);
  Extend(&c, c2.fn_max_n, c2.v_max_mm_s);
  return c;
}

// The span and missing region from the covered extent (out->covered, of
// clamped finite points; out->samples and out->missing set already) and
// hull_area(), the area of those points' hull, asked only when the extent
// has an area.
template <typename HullArea>
void FinishSpanCoverage(const SpanRect& reference,
                        SpanCoverage* result,
                        HullArea hull_area) {
  SpanCoverage& out = *result;
  const SpanRect& c = out.covered;
  // No extent on an axis (e.g. a constant load clamped to the reference):
  // the points lie on one line and the hull has no area.
  const bool flat =
      !(c.fn_max_n > c.fn_min_n) || !(c.v_max_mm_s > c.v_min_mm_s);
  out.span_pct =
      flat ? 0.0
           : std::clamp(100.0 * hull_area() / reference.Area(), 0.0, 100.0);
  // Missing region: per axis, the larger uncovered end when the covered
  // extent is below half of the reference range.
  auto missing_axis = [](double lo,
                         double hi,
                         double c_lo,
                         double c_hi,
                         double* m_lo,
                         double* m_hi) {
    if (c_hi - c_lo >= 0.5 * (hi - lo)) return;
    if (c_lo - lo >= hi - c_hi) {
      *m_lo = lo;
      *m_hi = c_lo;
    } else {
      *m_lo = c_hi;
      *m_hi = hi;
    }
  };
  missing_axis(reference.fn_min_n,
               reference.fn_max_n,
               c.fn_min_n,
               c.fn_max_n,
               &out.missing.fn_min_n,
               &out.missing.fn_max_n);
  missing_axis(reference.v_min_mm_s,
               reference.v_max_mm_s,
               c.v_min_mm_s,
               c.v_max_mm_s,
               &out.missing.v_min_mm_s,
               &out.missing.v_max_mm_s);
}

// Validates the arguments shared by both forms of CalcSpanCoverage.
void CheckSpanArguments(const std::vector<double>& fn_n,
                        const std::vector<double>& v_mm_s,
                        const SpanRect& reference) {
  if (!reference.IsValid())
    throw std::invalid_argument(
        "reference: fn and v ranges must be finite and non-empty");
  if (fn_n.size() != v_mm_s.size())
    throw std::invalid_argument("fn_n and v_mm_s differ in length (" +
                                std::to_string(fn_n.size()) + " vs " +
                                std::to_string(v_mm_s.size()) + ")");
}

}  // namespace

SpanCoverage CalcSpanCoverage(const std::vector<double>& fn_n,
                              const std::vector<double>& v_mm_s,
                              const SpanRect& reference) {
  CheckSpanArguments(fn_n, v_mm_s, reference);
  SpanCoverage out;
  out.missing = reference;
  std::vector<Point> points(fn_n.size());
  std::size_t kept = 0;
  for (std::size_t i = 0; i < fn_n.size(); ++i) {
    // Non-finite points are written and then overwritten.
    points[kept] = ClampInto(reference, fn_n[i], v_mm_s[i]);
    kept += std::isfinite(fn_n[i]) && std::isfinite(v_mm_s[i]);
  }
  points.resize(kept);
  out.samples = static_cast<int>(points.size());
  if (points.empty()) return out;
  out.covered = ExtentOf(points);
  FinishSpanCoverage(reference, &out, [&points] {
    return CalcConvexHullArea(std::move(points));
  });
  return out;
}

SpanCoverage CalcSpanCoverage(const std::vector<double>& fn_n,
                              const std::vector<double>& v_mm_s,
                              const SpanRect& reference,
                              const std::vector<int>& stroke,
                              IdentificationMemo* memo) {
  if (stroke.empty()) return CalcSpanCoverage(fn_n, v_mm_s, reference);
  CheckSpanArguments(fn_n, v_mm_s, reference);
  if (stroke.size() != fn_n.size())
    throw std::invalid_argument("stroke and fn_n differ in length (" +
                                std::to_string(stroke.size()) + " vs " +
                                std::to_string(fn_n.size()) + ")");
  SpanCoverage out;
  out.missing = reference;
  // The hull of the clamped points is the hull of the strokes' clamped
  // hulls (as in CalcMaterialHullCoverage), and so is their extent; a
  // stroke's clamped hull depends on its points and the reference only,
  // so a refit looks up its older strokes' hulls in the memo.
  const StrokeHulls strokes =
      CollectStrokeHulls(fn_n, v_mm_s, stroke, &reference, memo);
  out.samples = strokes.total;
  if (strokes.hulls.empty()) return out;
  out.covered = ExtentOf(strokes.BoxCorners());
  FinishSpanCoverage(
      reference, &out, [&strokes] { return PolygonArea(UnionHull(strokes)); });
  return out;
}

HullSpanCoverage CalcHullSpanCoverage(
    const std::vector<double>& fn_n,
    const std::vector<double>& v_mm_s,
    const std::vector<double>& material_fn_n,
    const std::vector<double>& material_v_mm_s) {
  if (fn_n.size() != v_mm_s.size())
    throw std::invalid_argument("fn_n and v_mm_s differ in length (" +
                                std::to_string(fn_n.size()) + " vs " +
                                std::to_string(v_mm_s.size()) + ")");
  if (material_fn_n.size() != material_v_mm_s.size())
    throw std::invalid_argument(
        "material_fn_n and material_v_mm_s differ in length (" +
        std::to_string(material_fn_n.size()) + " vs " +
        std::to_string(material_v_mm_s.size()) + ")");
  std::vector<std::pair<double, double>> subset, all;
  subset.reserve(fn_n.size());
  all.reserve(fn_n.size() + material_fn_n.size());
  for (std::size_t i = 0; i < fn_n.size(); ++i)
    if (std::isfinite(fn_n[i]) && std::isfinite(v_mm_s[i]))
      subset.emplace_back(fn_n[i], v_mm_s[i]);
  all = subset;
  for (std::size_t i = 0; i < material_fn_n.size(); ++i)
    if (std::isfinite(material_fn_n[i]) && std::isfinite(material_v_mm_s[i]))
      all.emplace_back(material_fn_n[i], material_v_mm_s[i]);
  HullSpanCoverage out;
  out.samples = static_cast<int>(subset.size());
  out.material_samples = static_cast<int>(all.size());
  out.hull_area = CalcConvexHullArea(std::move(subset));
  out.material_hull_area = CalcConvexHullArea(std::move(all));
  if (out.material_hull_area > 0)
    out.span_pct =
        std::clamp(100.0 * out.hull_area / out.material_hull_area, 0.0, 100.0);
  out.reliable = out.span_pct >= 50.0;
  return out;
}

MaterialHullCoverage CalcMaterialHullCoverage(const std::vector<double>& fn_n,
                                              const std::vector<double>& v_mm_s,
                                              const std::vector<int>& stroke,
                                              int max_strokes,
                                              IdentificationMemo* memo) {
  if (fn_n.size() != v_mm_s.size())
    throw std::invalid_argument("fn_n and v_mm_s differ in length (" +
                                std::to_string(fn_n.size()) + " vs " +
                                std::to_string(v_mm_s.size()) + ")");
  if (!stroke.empty() && stroke.size() != fn_n.size())
    throw std::invalid_argument("stroke and fn_n differ in length (" +
                                std::to_string(stroke.size()) + " vs " +
                                std::to_string(fn_n.size()) + ")");
  if (max_strokes < 0)
    throw std::invalid_argument("max_strokes = " + std::to_string(max_strokes) +
                                " (must be >= 0)");
  MaterialHullCoverage out;
  // The material's hull is the hull of the strokes' hulls (the strict
  // vertices of the hull of a union are vertices of the parts' hulls), so
  // with stroke ids each stroke's few points are sorted once and the whole
  // set never is: on the bundled 20,000 slipping samples of a thin band
  // (constant load) 0.77 -> 0.47 ms.
  std::vector<StrokeHullCoverage> strokes;
  if (stroke.empty()) {
    std::vector<Point> all;
    for (std::size_t i = 0; i < fn_n.size(); ++i) {
      if (!(std::isfinite(fn_n[i]) && std::isfinite(v_mm_s[i]))) continue;
      all.emplace_back(fn_n[i], v_mm_s[i]);
    }
    out.samples = static_cast<int>(all.size());
    out.hull = CalcConvexHull(std::move(all));
  } else {
    const StrokeHulls hulls =
        CollectStrokeHulls(fn_n, v_mm_s, stroke, nullptr, memo);
    out.samples = hulls.total;
    strokes.reserve(hulls.ids.size());
    for (std::size_t k = 0; k < hulls.ids.size(); ++k) {
      StrokeHullCoverage s;
      s.stroke = hulls.ids[k];
      s.coverage.samples = hulls.samples[k];
      s.coverage.hull_area = hulls.hulls[k]->area;
      strokes.push_back(s);
    }
    out.hull = UnionHull(hulls);
  }
  out.hull_area = PolygonArea(out.hull);
  std::size_t skip =
      strokes.size() > static_cast<std::size_t>(max_strokes)
          ? strokes.size() - static_cast<std::size_t>(max_strokes)
          : 0;
  for (StrokeHullCoverage& s : strokes) {
    if (skip > 0) {
      --skip;
      continue;
    }
    s.coverage.material_samples = out.samples;
    s.coverage.material_hull_area = out.hull_area;
    if (out.hull_area > 0)
      s.coverage.span_pct =
          std::clamp(100.0 * s.coverage.hull_area / out.hull_area, 0.0, 100.0);
    s.coverage.reliable = s.coverage.span_pct >= 50.0;
    out.strokes.push_back(s);
  }
  return out;
}

}  // namespace frictiond
