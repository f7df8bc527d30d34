#include "core/transfer/attributes.h"

#include <algorithm>
#include <cassert>
#include <cstdint>
#include <limits>
#include <map>
#include <numeric>
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
  const Eigen::Index nt = target.vertexCount(), nf = target.triangleCount();
  const Eigen::Index nsf = source_mesh.triangleCount();
  const Eigen::MatrixX3i& src_tris = source_mesh.triangles;
  const Eigen::MatrixX3d& src_positions = source_mesh.positions;
  const Eigen::MatrixXd& all_uvs = layout.uvs;
  const std::vector<int>& uv_of = layout.uv_of;
  const FacesAroundPoints& source_around = layout.around;
  const double same_uv = layout.same_uv;
  const Eigen::Index cols = all_uvs.cols();
  auto at = [](auto& values, auto i) -> decltype(auto) { return values[static_cast<std::size_t>(i)]; };
  TransferredUvLayout out;
  out.triangles = target.triangles;
  auto corner = [&](int face, int k) -> Eigen::Vector3d { return src_positions.row(src_tris(face, k)).transpose(); };
  // interpolateOnFace of all_uvs, as an expression (no row allocated per call)
  auto uvsAt = [&](int face, const Eigen::Vector3d& b) {
    return b(0) * all_uvs.row(src_tris(face, 0)) + b(1) * all_uvs.row(src_tris(face, 1)) + b(2) * all_uvs.row(src_tris(face, 2));
  };
  auto sourcePoint = [&](const SurfacePoint& sp) -> Eigen::Vector3d {
    return interpolateOnFace(src_positions, src_tris, sp.face, sp.barycentric).transpose();
  };
  // Every located vertex takes the UVs of its location, mismatched ones too
  // (their place is off, but on the surface they face): inpainting them
  // would blend the charts of the vertices around them.
  // uvs: the UVs of each vertex's own location (0 when it has none), then
  // rows for the copies.
  std::vector<char> located(static_cast<std::size_t>(nt));
  Eigen::MatrixXd uvs = Eigen::MatrixXd::Zero(nt, cols);
  for (Eigen::Index v = 0; v < nt; ++v) {
    const SurfacePoint& sp = at(locations.on_source, v);
    at(located, v) = sp.found();
    if (sp.found()) uvs.row(v) = uvsAt(sp.face, sp.barycentric);
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
  std::vector<char> split_point(static_cast<std::size_t>(nt), 0);
  for (std::size_t v = 0; v < target_point.size(); ++v) {
    if (target_point[v] != static_cast<int>(v)) split_point[v] = split_point[static_cast<std::size_t>(target_point[v])] = 1;
  }
  Eigen::MatrixXd corner_uvs(3 * nf, cols);
  std::vector<char> corner_extended(static_cast<std::size_t>(3 * nf), 0);
  std::vector<int> faces, sides, ring, region;  // faces: located corners'; sides: those that tell the side
  std::vector<int> visited(static_cast<std::size_t>(nsf), 0), in_region(visited);  // stamps of searches
  int searches = 0;
  auto sharesUvPoint = [&](int a, int b) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        if (at(uv_of, src_tris(a, i)) == at(uv_of, src_tris(b, j))) return true;
      }
    }
    return false;
  };
  auto nearestOf = [&](const Eigen::Vector3d& p, const std::vector<int>& candidates) {
    int nearest = -1;
    double nearest_sq = std::numeric_limits<double>::infinity();
    for (const int h : candidates) {
      const double sq = closestPointOnTriangle(p, corner(h, 0), corner(h, 1), corner(h, 2)).sq_distance;
      if (sq < nearest_sq) {
        nearest_sq = sq;
        nearest = h;
      }
    }
    return nearest;
  };
  for (Eigen::Index f = 0; f < nf; ++f) {
    faces.clear();
    sides.clear();
    for (int k = 0; k < 3; ++k) {
      const int v = target.triangles(f, k);
      if (!at(located, v)) continue;
      faces.push_back(at(locations.on_source, v).face);
      if (!at(split_point, v)) sides.push_back(faces.back());
    }
    if (faces.empty()) continue;
    if (sides.empty()) sides = faces;
    // First without a search: faces that meet the first at a point with one
    // UV, or meet one of the faces across its UV-continuous edges so.
    auto nextToFirst = [&](int g) {
      if (g == faces.front() || sharesUvPoint(g, faces.front())) return true;
      const auto first = static_cast<std::size_t>(faces.front());
      for (int i = layout.across_offsets[first]; i < layout.across_offsets[first + 1]; ++i) {
        if (sharesUvPoint(g, at(layout.across_faces, i))) return true;
      }
      return false;
    };
    const bool one_side = std::all_of(faces.begin(), faces.end(), nextToFirst);
    int search = 0;  // the region's stamp
    if (!one_side) {
      Eigen::Vector3d centre = Eigen::Vector3d::Zero(), side_centre = Eigen::Vector3d::Zero();
      std::vector<Eigen::Vector3d> points;
      for (int k = 0; k < 3; ++k) {
        const int v = target.triangles(f, k);
        if (!at(located, v)) continue;
        points.push_back(sourcePoint(at(locations.on_source, v)));
        centre += points.back() / static_cast<double>(faces.size());
        if (!at(split_point, v) || sides.size() == faces.size()) side_centre += points.back() / static_cast<double>(sides.size());
      }
      double reach = 0.0;
      for (const auto& p : points) reach = std::max(reach, (p - centre).norm());
      // Faces reachable from `start` across edges with one UV, near the face;
      // with `until_reached`, only until every located corner's face is.
      auto sideOf = [&](int start, bool until_reached) {
        search = ++searches;
        region.assign(1, start);
        at(visited, start) = at(in_region, start) = search;
        auto reached = [&] { return std::all_of(faces.begin(), faces.end(), [&](int g) { return at(in_region, g) == search; }); };
        for (std::size_t q = 0; q < region.size() && !(until_reached && reached()); ++q) {
          const auto g = static_cast<std::size_t>(region[q]);
          for (int i = layout.across_offsets[g]; i < layout.across_offsets[g + 1]; ++i) {
            const int h = at(layout.across_faces, i);
            if (at(visited, h) == search) continue;
            at(visited, h) = search;
            if ((layout.face_centres.row(h).transpose() - centre).norm() <= 1.5 * reach + layout.face_radii(h)) {
              region.push_back(h);
              at(in_region, h) = search;
            }
          }
        }
      };
      sideOf(sides.front(), true);
      if (!std::all_of(sides.begin(), sides.end(), [&](int g) { return at(in_region, g) == search; })) {
        // The side-telling corners lie across a seam: the side of the face
        // nearest their middle, among those around their faces.
        ring.clear();
        ++searches;
        for (const int g : sides) {
          for (int k = 0; k < 3; ++k) {
            source_around.forEachFaceAround(src_tris(g, k), [&](int h) {
              if (at(visited, h) != searches) ring.push_back(h);
              at(visited, h) = searches;
            });
          }
        }
        sideOf(nearestOf(side_centre, ring), false);
      }  // else: a corner not reached left the whole side near the face in the region, to extend it from
    }
    for (int k = 0; k < 3; ++k) {
      const int v = target.triangles(f, k);
      if (!at(located, v)) continue;
      const SurfacePoint& sp = at(locations.on_source, v);
      const Eigen::Index row = 3 * f + k;
      if (one_side || at(in_region, sp.face) == search) {
        corner_uvs.row(row) = uvs.row(v);
        continue;
      }
      const Eigen::Vector3d p = sourcePoint(sp);
      const int g = nearestOf(p, region);
      corner_uvs.row(row) = uvsAt(g, planeBarycentric(p, corner(g, 0), corner(g, 1), corner(g, 2)));
      at(corner_extended, row) = 1;
    }
  }

  // One vertex per distinct UV of a target vertex's corners: the target's own
  // index for the UVs of its location (else its first corner's), copies after
  // the target's vertices for the others. Unlocated vertices stay one vertex.
  std::vector<char> home_used(static_cast<std::size_t>(nt), 0), extended(static_cast<std::size_t>(nt), 0);
  auto same = [&](const auto& a, const auto& b) { return (a - b).norm() <= same_uv; };
  for (Eigen::Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = target.triangles(f, k);
      if (at(located, v) && same(corner_uvs.row(3 * f + k), uvs.row(v))) at(home_used, v) = 1;
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
        uvs.row(v) = corner_uvs.row(row);
        at(extended, v) = at(corner_extended, row);
      }
      at(placed, v) = 1;
      if (same(corner_uvs.row(row), uvs.row(v))) continue;
      std::vector<int>& mine = at(copies, v);
      const auto found = std::find_if(mine.begin(), mine.end(), [&](int c) { return same(at(copy_uvs, c - nt), corner_uvs.row(row)); });
      if (found != mine.end()) {
        out.triangles(f, k) = *found;
        continue;
      }
      const int index = static_cast<int>(nt) + static_cast<int>(out.copy_of.size());
      out.copy_of.push_back(v);
      copy_uvs.push_back(corner_uvs.row(row));
      extended.push_back(at(corner_extended, row));
      mine.push_back(index);
      out.triangles(f, k) = index;
    }
  }
  const Eigen::Index n = nt + static_cast<Eigen::Index>(out.copy_of.size());
  uvs.conservativeResize(n, cols);
  for (std::size_t c = 0; c < copy_uvs.size(); ++c) uvs.row(nt + static_cast<Eigen::Index>(c)) = copy_uvs[c];
  out.extended_vertices = static_cast<int>(std::count(extended.begin(), extended.end(), 1));

  // Unlocated vertices inpainted on the split target, the copies of a point
  // joined only where their UVs agree.
  if (std::find(located.begin(), located.end(), 0) != located.end()) {
    std::vector<char> known(located);
    known.resize(static_cast<std::size_t>(n), 1);
    Eigen::MatrixX3d positions(n, 3);
    positions.topRows(nt) = target.positions;
    for (std::size_t c = 0; c < out.copy_of.size(); ++c) {
      positions.row(nt + static_cast<Eigen::Index>(c)) = target.positions.row(out.copy_of[c]);
    }
    const Eigen::SparseMatrix<double> laplacian =
        uniformLaplacian(out.triangles, n, agreeingVertexRepresentatives(positions, uvs));
    auto inpainted = inpaintHarmonic(laplacian, known, uvs);
    if (!inpainted) return Error{inpainted.error().code, "inpainting UVs: " + inpainted.error().message};
    uvs = std::move(*inpainted);
  }
  for (Eigen::Index s = 0; s < cols / 2; ++s) out.sets.push_back(uvs.middleCols(2 * s, 2));
  return out;
}

}  // namespace core
