#include "core/transfer/attributes.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cstdint>
#include <limits>
#include <map>
#include <numeric>
#include <span>
#include <string>
#include <vector>

namespace core {

namespace {

Eigen::MatrixXd interpolate(const Eigen::MatrixXd& values, const Eigen::MatrixX3i& triangles,
                            const TargetLocations& locations, Eigen::Index nt) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(nt, values.cols());
  for (Eigen::Index v = 0; v < nt; ++v) {
    const SurfacePoint& sp = locations.on_source[static_cast<std::size_t>(v)];
    if (!sp.found()) continue;
    out.row(v) = interpolateOnFace(values, triangles, sp.face, sp.barycentric);
  }
  return out;
}

// Labels of untrusted vertices: majority of already-labelled neighbours,
// growing outward from the trusted ones (ties: lower label).
void fillUntrustedLabels(Eigen::VectorXi& labels, std::vector<char> assigned, const Eigen::SparseMatrix<double>& laplacian) {
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<std::pair<int, int>> updates;
    for (int v = 0; v < laplacian.outerSize(); ++v) {
      if (assigned[static_cast<std::size_t>(v)]) continue;
      std::map<int, int> votes;
      for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, v); it; ++it) {
        if (it.row() != v && assigned[static_cast<std::size_t>(it.row())]) ++votes[labels(it.row())];
      }
      if (votes.empty()) continue;
      const auto best = std::max_element(votes.begin(), votes.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
      updates.emplace_back(v, best->first);
    }
    for (const auto& [v, label] : updates) {
      labels(v) = label;
      assigned[static_cast<std::size_t>(v)] = 1;
      changed = true;
    }
  }
}

}  // namespace

VertexAttributes transferAttributes(const Mesh& source_mesh, const VertexAttributes& source,
                                    const TargetLocations& locations, const Eigen::SparseMatrix<double>& target_laplacian,
                                    const HarmonicInpainting* mismatched) {
  VertexAttributes out;
  const Eigen::Index nt = locations.confidence.size();
  std::vector<char> trusted(static_cast<std::size_t>(nt));
  bool any_untrusted = false;
  for (Eigen::Index v = 0; v < nt; ++v) {
    trusted[static_cast<std::size_t>(v)] = locations.mismatched(v) == 0;
    any_untrusted = any_untrusted || !trusted[static_cast<std::size_t>(v)];
  }
  assert(!any_untrusted || ((source.labels.empty() || target_laplacian.rows() == nt) &&
                            ((source.colors.rows() == 0 && source.fields.empty()) || mismatched != nullptr)));
  auto inpaint = [&](const Eigen::MatrixXd& values) -> Eigen::MatrixXd {
    return mismatched != nullptr ? mismatched->apply(values) : values;
  };
  const Eigen::MatrixX3i& tris = source_mesh.triangles;
  if (source.colors.rows() > 0) out.colors = inpaint(interpolate(source.colors, tris, locations, nt));
  for (const auto& [name, field] : source.fields) out.fields[name] = inpaint(interpolate(field, tris, locations, nt));
  for (const auto& [name, labels] : source.labels) {
    Eigen::VectorXi result = Eigen::VectorXi::Zero(nt);
    for (Eigen::Index v = 0; v < nt; ++v) {
      const SurfacePoint& sp = locations.on_source[static_cast<std::size_t>(v)];
      if (!sp.found()) continue;
      // Majority by barycentric weight; ties go to the lower label.
      int best = labels(tris(sp.face, 0));
      double best_weight = -1.0;
      for (int k = 0; k < 3; ++k) {
        const int label = labels(tris(sp.face, k));
        double w = 0.0;
        for (int m = 0; m < 3; ++m) if (labels(tris(sp.face, m)) == label) w += sp.barycentric(m);
        if (w > best_weight || (w == best_weight && label < best)) {
          best_weight = w;
          best = label;
        }
      }
      result(v) = best;
    }
    if (any_untrusted) fillUntrustedLabels(result, trusted, target_laplacian);
    out.labels[name] = result;
  }
  return out;
}

namespace {

// Barycentric coordinates of p's projection onto the plane of (a, b, c),
// outside the triangle too; the closest point's when the triangle is
// degenerate.
Eigen::Vector3d planeBarycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                 const Eigen::Vector3d& c) {
  const Eigen::Vector3d e0 = b - a, e1 = c - a, d = p - a;
  const double d00 = e0.squaredNorm(), d01 = e0.dot(e1), d11 = e1.squaredNorm();
  const double det = d00 * d11 - d01 * d01;
  if (!(det > 1e-12 * d00 * d11)) return closestPointOnTriangle(p, a, b, c).barycentric;
  const double u = (d11 * d.dot(e0) - d01 * d.dot(e1)) / det;
  const double w = (d00 * d.dot(e1) - d01 * d.dot(e0)) / det;
  return {1.0 - u - w, u, w};
}

// Faces across each edge whose two ends carry one UV (uv_of: vertices at one
// point with one UV share a representative), as CSR by face: the UV layout
// is continuous between them.
struct UvNeighbours {
  std::vector<int> offsets;  // #F + 1
  std::vector<int> faces;
};
UvNeighbours uvNeighbours(const Eigen::MatrixX3i& tris, const std::vector<int>& uv_of) {
  const Eigen::Index nf = tris.rows();
  std::vector<std::pair<std::uint64_t, int>> edges;
  edges.reserve(static_cast<std::size_t>(3 * nf));
  for (Eigen::Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      auto a = static_cast<std::uint32_t>(uv_of[static_cast<std::size_t>(tris(f, k))]);
      auto b = static_cast<std::uint32_t>(uv_of[static_cast<std::size_t>(tris(f, (k + 1) % 3))]);
      if (a == b) continue;
      if (a > b) std::swap(a, b);
      edges.emplace_back((static_cast<std::uint64_t>(a) << 32) | b, static_cast<int>(f));
    }
  }
  std::sort(edges.begin(), edges.end());
  // Every face of an edge's group is across it from every other.
  UvNeighbours out;
  out.offsets.assign(static_cast<std::size_t>(nf) + 1, 0);
  auto forEachPair = [&](auto&& fn) {
    for (std::size_t i = 0, j = 0; i < edges.size(); i = j) {
      for (j = i + 1; j < edges.size() && edges[j].first == edges[i].first; ++j) {
      }
      for (std::size_t x = i; x < j; ++x) {
        for (std::size_t y = i; y < j; ++y) {
          if (x != y) fn(edges[x].second, edges[y].second);
        }
      }
    }
  };
  forEachPair([&](int f, int) { ++out.offsets[static_cast<std::size_t>(f) + 1]; });
  for (std::size_t f = 0; f + 1 < out.offsets.size(); ++f) out.offsets[f + 1] += out.offsets[f];
  out.faces.resize(static_cast<std::size_t>(out.offsets.back()));
  std::vector<int> fill(out.offsets.begin(), out.offsets.end() - 1);
  forEachPair([&](int f, int g) { out.faces[static_cast<std::size_t>(fill[static_cast<std::size_t>(f)]++)] = g; });
  return out;
}

// transferUvLayout's stages.

// values[i] for an Eigen or int index.
template <typename Values, typename Index>
decltype(auto) at(Values& values, Index i) {
  return values[static_cast<std::size_t>(i)];
}

Eigen::Vector3d sourceCorner(const Mesh& source_mesh, int face, int k) {
  return source_mesh.positions.row(source_mesh.triangles(face, k)).transpose();
}

Eigen::Vector3d sourcePoint(const Mesh& source_mesh, const SurfacePoint& sp) {
  return interpolateOnFace(source_mesh.positions, source_mesh.triangles, sp.face, sp.barycentric).transpose();
}

// interpolateOnFace of the layout's UVs, as an expression (no row allocated per call).
auto uvsAt(const SourceUvLayout& layout, const Eigen::MatrixX3i& tris, int face, const Eigen::Vector3d& b) {
  return b(0) * layout.uvs.row(tris(face, 0)) + b(1) * layout.uvs.row(tris(face, 1)) +
         b(2) * layout.uvs.row(tris(face, 2));
}

// Every located vertex takes the UVs of its location, mismatched ones too
// (their place is off, but on the surface they face): inpainting them
// would blend the charts of the vertices around them.
struct LocatedUvs {
  std::vector<char> located;  // #Vt: has a location on the source
  Eigen::MatrixXd uvs;        // #Vt by 2 x #sets: the UVs of its location (0 when it has none)
};

LocatedUvs uvsAtLocations(const Mesh& source_mesh, const SourceUvLayout& layout, const TargetLocations& locations,
                          Eigen::Index nt) {
  LocatedUvs out;
  out.located.resize(static_cast<std::size_t>(nt));
  out.uvs = Eigen::MatrixXd::Zero(nt, layout.uvs.cols());
  for (Eigen::Index v = 0; v < nt; ++v) {
    const SurfacePoint& sp = at(locations.on_source, v);
    at(out.located, v) = sp.found();
    if (sp.found()) out.uvs.row(v) = uvsAt(layout, source_mesh.triangles, sp.face, sp.barycentric);
  }
  return out;
}

// Target vertices split at a point (on the target's own UV seam): #Vt flags.
std::vector<char> splitPoints(const std::vector<int>& target_point, Eigen::Index nt) {
  std::vector<char> split_point(static_cast<std::size_t>(nt), 0);
  for (std::size_t v = 0; v < target_point.size(); ++v) {
    if (target_point[v] != static_cast<int>(v)) split_point[v] = split_point[static_cast<std::size_t>(target_point[v])] = 1;
  }
  return split_point;
}

bool sharesUvPoint(const Eigen::MatrixX3i& tris, const std::vector<int>& uv_of, int a, int b) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (at(uv_of, tris(a, i)) == at(uv_of, tris(b, j))) return true;
    }
  }
  return false;
}

// The face of `candidates` nearest p (-1 when none).
int nearestFace(const Mesh& source_mesh, const Eigen::Vector3d& p, const std::vector<int>& candidates) {
  int nearest = -1;
  double nearest_sq = std::numeric_limits<double>::infinity();
  for (const int h : candidates) {
    const double sq =
        closestPointOnTriangle(p, sourceCorner(source_mesh, h, 0), sourceCorner(source_mesh, h, 1),
                               sourceCorner(source_mesh, h, 2)).sq_distance;
    if (sq < nearest_sq) {
      nearest_sq = sq;
      nearest = h;
    }
  }
  return nearest;
}

// A target face's located corners: the source faces of their locations, in
// corner order, and those of the corners that tell the side (not at a point
// the target splits; all of them when none is).
struct LocatedCorners {
  std::array<int, 3> face{};
  std::array<int, 3> side_face{};
  std::size_t count = 0, side_count = 0;
  std::span<const int> faces() const { return {face.data(), count}; }
  std::span<const int> sides() const { return side_count > 0 ? std::span<const int>(side_face.data(), side_count) : faces(); }
};

LocatedCorners locatedCorners(const Eigen::Vector3i& triangle, const std::vector<char>& located,
                              const std::vector<char>& split_point, const TargetLocations& locations) {
  LocatedCorners out;
  for (int k = 0; k < 3; ++k) {
    const int v = triangle(k);
    if (!at(located, v)) continue;
    out.face[out.count++] = at(locations.on_source, v).face;
    if (!at(split_point, v)) out.side_face[out.side_count++] = out.face[out.count - 1];
  }
  return out;
}

// The corners' locations are on one side of any seam, found without a
// search: their faces meet the first at a point with one UV, or meet one of
// the faces across its UV-continuous edges so.
bool onOneSide(const Eigen::MatrixX3i& tris, const SourceUvLayout& layout, std::span<const int> faces) {
  auto nextToFirst = [&](int g) {
    if (g == faces.front() || sharesUvPoint(tris, layout.uv_of, g, faces.front())) return true;
    const auto first = static_cast<std::size_t>(faces.front());
    for (int i = layout.across_offsets[first]; i < layout.across_offsets[first + 1]; ++i) {
      if (sharesUvPoint(tris, layout.uv_of, g, at(layout.across_faces, i))) return true;
    }
    return false;
  };
  return std::all_of(faces.begin(), faces.end(), nextToFirst);
}

// Where a target face's located corners lie on the source: their mean, the
// mean of those that tell the side, and the farthest from the mean.
struct CornerSpread {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d side_centre = Eigen::Vector3d::Zero();
  double reach = 0.0;
};

CornerSpread cornerSpread(const Mesh& source_mesh, const Eigen::Vector3i& triangle, const std::vector<char>& located,
                          const std::vector<char>& split_point, const TargetLocations& locations,
                          const LocatedCorners& corners) {
  const std::span<const int> faces = corners.faces(), sides = corners.sides();
  CornerSpread out;
  std::vector<Eigen::Vector3d> points;
  for (int k = 0; k < 3; ++k) {
    const int v = triangle(k);
    if (!at(located, v)) continue;
    points.push_back(sourcePoint(source_mesh, at(locations.on_source, v)));
    out.centre += points.back() / static_cast<double>(faces.size());
    if (!at(split_point, v) || sides.size() == faces.size()) out.side_centre += points.back() / static_cast<double>(sides.size());
  }
  for (const auto& p : points) out.reach = std::max(out.reach, (p - out.centre).norm());
  return out;
}

// Source faces found by the searches for a seam's side (chooseSeamSide).
// Stamps, not flags: a search needs no clearing.
struct SeamSideSearch {
  explicit SeamSideSearch(Eigen::Index source_faces)
      : visited(static_cast<std::size_t>(source_faces), 0), in_region(visited) {}
  std::vector<int> visited, in_region;  // per source face: the last search (stamp) that visited / took it
  std::vector<int> region;              // the faces the last search took
  std::vector<int> ring;
  int searches = 0;
};

// Faces reachable from `start` across edges with one UV, near the face
// (within 1.5 reach of its centre); with `until_reached`, only until every
// located corner's face is. Returns the search's stamp.
int growSide(const SourceUvLayout& layout, std::span<const int> faces, const CornerSpread& spread, int start,
             bool until_reached, SeamSideSearch& s) {
  const int search = ++s.searches;
  s.region.assign(1, start);
  at(s.visited, start) = at(s.in_region, start) = search;
  auto reached = [&] { return std::all_of(faces.begin(), faces.end(), [&](int g) { return at(s.in_region, g) == search; }); };
  for (std::size_t q = 0; q < s.region.size() && !(until_reached && reached()); ++q) {
    const auto g = static_cast<std::size_t>(s.region[q]);
    for (int i = layout.across_offsets[g]; i < layout.across_offsets[g + 1]; ++i) {
      const int h = at(layout.across_faces, i);
      if (at(s.visited, h) == search) continue;
      at(s.visited, h) = search;
      if ((layout.face_centres.row(h).transpose() - spread.centre).norm() <= 1.5 * spread.reach + layout.face_radii(h)) {
        s.region.push_back(h);
        at(s.in_region, h) = search;
      }
    }
  }
  return search;
}

// The side of a face whose corners' locations are not on one side: the side
// of its side-telling corners when they lie on one, else that of the source
// face nearest their middle, among those around their faces. Returns the
// stamp of the search whose region (s.region) is that side near the face.
int chooseSeamSide(const Mesh& source_mesh, const SourceUvLayout& layout, const LocatedCorners& corners,
                   const CornerSpread& spread, SeamSideSearch& s) {
  const std::span<const int> sides = corners.sides();
  const int search = growSide(layout, corners.faces(), spread, sides.front(), true, s);
  // A corner not reached left the whole side near the face in the region, to extend it from.
  if (std::all_of(sides.begin(), sides.end(), [&](int g) { return at(s.in_region, g) == search; })) return search;
  // The side-telling corners lie across a seam.
  s.ring.clear();
  ++s.searches;
  for (const int g : sides) {
    for (int k = 0; k < 3; ++k) {
      layout.around.forEachFaceAround(source_mesh.triangles(g, k), [&](int h) {
        if (at(s.visited, h) != s.searches) s.ring.push_back(h);
        at(s.visited, h) = s.searches;
      });
    }
  }
  return growSide(layout, corners.faces(), spread, nearestFace(source_mesh, spread.side_centre, s.ring), false, s);
}

// Each corner's UVs in the frame of its target face, from one side of any
// seam: the side its corners' locations are on, when they are on one
// (reachable from each other across source edges whose ends carry one UV,
// near the face); else the side of the source face nearest their mean
// location. Corners on that side interpolate their own location, the
// others (across the seam) extend it affinely from its face nearest them.
// A target vertex split at a point (its own UV seam) is located at the
// point, which may lie on the source's seam; its triangle's other corners
// tell the side.
struct CornerUvs {
  Eigen::MatrixXd uvs;          // 3 #Ft by 2 x #sets (row 3f + k), rows of unlocated corners unset
  std::vector<char> extended;   // 3 #Ft: extends a side past its seam
};

CornerUvs cornerUvs(const Mesh& source_mesh, const SourceUvLayout& layout, const Mesh& target,
                    const TargetLocations& locations, const LocatedUvs& own, const std::vector<char>& split_point) {
  const Eigen::Index nf = target.triangleCount();
  const Eigen::MatrixX3i& src_tris = source_mesh.triangles;
  CornerUvs out;
  out.uvs.resize(3 * nf, layout.uvs.cols());
  out.extended.assign(static_cast<std::size_t>(3 * nf), 0);
  SeamSideSearch search(source_mesh.triangleCount());
  for (Eigen::Index f = 0; f < nf; ++f) {
    const Eigen::Vector3i triangle = target.triangles.row(f).transpose();
    const LocatedCorners corners = locatedCorners(triangle, own.located, split_point, locations);
    if (corners.count == 0) continue;
    const bool one_side = onOneSide(src_tris, layout, corners.faces());
    const int side = one_side ? 0 : chooseSeamSide(source_mesh, layout, corners,
                                                   cornerSpread(source_mesh, triangle, own.located, split_point,
                                                                locations, corners),
                                                   search);
    for (int k = 0; k < 3; ++k) {
      const int v = triangle(k);
      if (!at(own.located, v)) continue;
      const SurfacePoint& sp = at(locations.on_source, v);
      const Eigen::Index row = 3 * f + k;
      if (one_side || at(search.in_region, sp.face) == side) {
        out.uvs.row(row) = own.uvs.row(v);
        continue;
      }
      const Eigen::Vector3d p = sourcePoint(source_mesh, sp);
      const int g = nearestFace(source_mesh, p, search.region);
      out.uvs.row(row) = uvsAt(layout, src_tris, g,
                               planeBarycentric(p, sourceCorner(source_mesh, g, 0), sourceCorner(source_mesh, g, 1),
                                                sourceCorner(source_mesh, g, 2)));
      at(out.extended, row) = 1;
    }
  }
  return out;
}

// The target split along the source's seams: one vertex per distinct UV of
// a target vertex's corners, the target's own index for the UVs of its
// location (else its first corner's), copies after the target's vertices for
// the others. Unlocated vertices stay one vertex.
struct SplitTarget {
  Eigen::MatrixX3i triangles;   // the target's, corners re-pointed to their copies
  std::vector<int> copy_of;     // the target vertex each appended vertex copies
  Eigen::MatrixXd uvs;          // #Vt + copy_of.size() by 2 x #sets (unlocated vertices' rows 0)
  int extended_vertices = 0;    // vertices whose UVs extend a side past its seam
};

// located, uvs: LocatedUvs.
SplitTarget splitAtSeams(const Mesh& target, const std::vector<char>& located, Eigen::MatrixXd uvs,
                         const CornerUvs& corners, double same_uv) {
  const Eigen::Index nt = target.vertexCount(), nf = target.triangleCount();
  SplitTarget out;
  out.triangles = target.triangles;
  std::vector<char> home_used(static_cast<std::size_t>(nt), 0), extended(static_cast<std::size_t>(nt), 0);
  auto same = [&](const auto& a, const auto& b) { return (a - b).norm() <= same_uv; };
  for (Eigen::Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = target.triangles(f, k);
      if (at(located, v) && same(corners.uvs.row(3 * f + k), uvs.row(v))) at(home_used, v) = 1;
    }
  }
  std::vector<char> placed(static_cast<std::size_t>(nt), 0);
  std::vector<std::vector<int>> copies(static_cast<std::size_t>(nt));
  std::vector<Eigen::RowVectorXd> copy_uvs;
  for (Eigen::Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = target.triangles(f, k);
      const Eigen::Index row = 3 * f + k;
      if (!at(located, v)) continue;
      if (!at(home_used, v) && !at(placed, v)) {  // the UVs of its own location are on none of its faces
        uvs.row(v) = corners.uvs.row(row);
        at(extended, v) = at(corners.extended, row);
      }
      at(placed, v) = 1;
      if (same(corners.uvs.row(row), uvs.row(v))) continue;
      std::vector<int>& mine = at(copies, v);
      const auto found = std::find_if(mine.begin(), mine.end(), [&](int c) { return same(at(copy_uvs, c - nt), corners.uvs.row(row)); });
      if (found != mine.end()) {
        out.triangles(f, k) = *found;
        continue;
      }
      const int index = static_cast<int>(nt) + static_cast<int>(out.copy_of.size());
      out.copy_of.push_back(v);
      copy_uvs.push_back(corners.uvs.row(row));
      extended.push_back(at(corners.extended, row));
      mine.push_back(index);
      out.triangles(f, k) = index;
    }
  }
  const Eigen::Index n = nt + static_cast<Eigen::Index>(out.copy_of.size());
  uvs.conservativeResize(n, uvs.cols());
  for (std::size_t c = 0; c < copy_uvs.size(); ++c) uvs.row(nt + static_cast<Eigen::Index>(c)) = copy_uvs[c];
  out.uvs = std::move(uvs);
  out.extended_vertices = static_cast<int>(std::count(extended.begin(), extended.end(), 1));
  return out;
}

// Unlocated vertices inpainted on the split target, the copies of a point
// joined only where their UVs agree. located: #Vt (the copies count as known).
Result<Eigen::MatrixXd> inpaintUnlocatedUvs(const Mesh& target, const SplitTarget& split,
                                            const std::vector<char>& located) {
  const Eigen::Index nt = target.vertexCount(), n = split.uvs.rows();
  std::vector<char> known(located);
  known.resize(static_cast<std::size_t>(n), 1);
  Eigen::MatrixX3d positions(n, 3);
  positions.topRows(nt) = target.positions;
  for (std::size_t c = 0; c < split.copy_of.size(); ++c) {
    positions.row(nt + static_cast<Eigen::Index>(c)) = target.positions.row(split.copy_of[c]);
  }
  const Eigen::SparseMatrix<double> laplacian =
      uniformLaplacian(split.triangles, n, agreeingVertexRepresentatives(positions, split.uvs));
  auto inpainted = inpaintHarmonic(laplacian, known, split.uvs);
  if (!inpainted) return Error{inpainted.error().code, "inpainting UVs: " + inpainted.error().message};
  return std::move(*inpainted);
}

}  // namespace

std::size_t SourceUvLayout::memoryBytes() const {
  return static_cast<std::size_t>(uvs.size() + face_centres.size() + face_radii.size()) * sizeof(double) +
         (uv_of.size() + around.point.size() + around.offsets.size() + around.faces.size() + across_offsets.size() +
          across_faces.size()) * sizeof(int);
}

Result<SourceUvLayout> prepareUvLayout(const Mesh& source_mesh, const std::vector<Eigen::MatrixX2d>& sets,
                                       const std::string& label) {
  const Eigen::Index ns = source_mesh.vertexCount(), nsf = source_mesh.triangleCount();
  const Eigen::MatrixX3i& tris = source_mesh.triangles;
  for (std::size_t s = 0; s < sets.size(); ++s) {
    if (sets[s].rows() != ns) {
      return Error{ErrorCode::kInvalidMesh, label + ": UV set " + std::to_string(s) + " has " +
                                                std::to_string(sets[s].rows()) + " rows for " + std::to_string(ns) +
                                                " vertices"};
    }
  }
  SourceUvLayout layout;
  layout.uvs.resize(ns, 2 * static_cast<Eigen::Index>(sets.size()));
  for (std::size_t s = 0; s < sets.size(); ++s) layout.uvs.middleCols(2 * static_cast<Eigen::Index>(s), 2) = sets[s];
  layout.uv_of = agreeingVertexRepresentatives(source_mesh.positions, layout.uvs);
  if (layout.uv_of.empty()) {
    layout.uv_of.resize(static_cast<std::size_t>(ns));
    std::iota(layout.uv_of.begin(), layout.uv_of.end(), 0);
  }
  layout.around = FacesAroundPoints(source_mesh, coincidentVertexRepresentatives(source_mesh.positions));
  UvNeighbours across = uvNeighbours(tris, layout.uv_of);
  layout.across_offsets = std::move(across.offsets);
  layout.across_faces = std::move(across.faces);
  layout.face_centres.resize(nsf, 3);
  layout.face_radii.resize(nsf);
  double uv_edges = 0.0;
  for (Eigen::Index f = 0; f < nsf; ++f) {
    const Eigen::RowVector3d c = (source_mesh.positions.row(tris(f, 0)) + source_mesh.positions.row(tris(f, 1)) +
                                  source_mesh.positions.row(tris(f, 2))) / 3.0;
    layout.face_centres.row(f) = c;
    layout.face_radii(f) = 0.0;
    for (int k = 0; k < 3; ++k) {
      layout.face_radii(f) = std::max(layout.face_radii(f), (source_mesh.positions.row(tris(f, k)) - c).norm());
      uv_edges += (layout.uvs.row(tris(f, k)) - layout.uvs.row(tris(f, (k + 1) % 3))).norm();
    }
  }
  // A tenth of the mean UV edge: extensions of one side made from
  // neighbouring faces differ a little, the two sides of a seam a lot.
  layout.same_uv = nsf > 0 ? 0.1 * uv_edges / static_cast<double>(3 * nsf) : 0.0;
  return layout;
}

Result<TransferredUvLayout> transferUvLayout(const Mesh& source_mesh, const SourceUvLayout& layout, const Mesh& target,
                                             const TargetLocations& locations, const std::vector<int>& target_point) {
  const Eigen::Index nt = target.vertexCount();
  LocatedUvs own = uvsAtLocations(source_mesh, layout, locations, nt);
  const CornerUvs corners = cornerUvs(source_mesh, layout, target, locations, own, splitPoints(target_point, nt));
  SplitTarget split = splitAtSeams(target, own.located, std::move(own.uvs), corners, layout.same_uv);
  if (std::find(own.located.begin(), own.located.end(), 0) != own.located.end()) {
    auto inpainted = inpaintUnlocatedUvs(target, split, own.located);
    if (!inpainted) return inpainted.error();
    split.uvs = std::move(*inpainted);
  }
  TransferredUvLayout out;
  out.triangles = std::move(split.triangles);
  out.copy_of = std::move(split.copy_of);
  for (Eigen::Index s = 0; s < split.uvs.cols() / 2; ++s) out.sets.push_back(split.uvs.middleCols(2 * s, 2));
  out.extended_vertices = split.extended_vertices;
  return out;
}

}  // namespace core
