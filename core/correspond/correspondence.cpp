// Dense correspondence by closest-point projection ("Stick", papers 004 eq. 4)
// and the inverse location of target vertices on the guide.
#include "core/correspond/correspondence.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>

#include "core/base/vector_clones.h"

namespace core {

std::vector<std::uint64_t> faceRegionSets(const Eigen::VectorXi& vertex_regions, const Eigen::MatrixX3i& triangles) {
  std::vector<std::uint64_t> sets(static_cast<std::size_t>(triangles.rows()), 0);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) sets[static_cast<std::size_t>(f)] |= std::uint64_t{1} << vertex_regions(triangles(f, k));
  }
  return sets;
}

std::vector<std::uint64_t> vertexRegionBits(const Eigen::VectorXi& vertex_regions) {
  std::vector<std::uint64_t> bits(static_cast<std::size_t>(vertex_regions.size()));
  for (Eigen::Index v = 0; v < vertex_regions.size(); ++v) bits[static_cast<std::size_t>(v)] = std::uint64_t{1} << vertex_regions(v);
  return bits;
}

GuideModel projectToTarget(const Eigen::MatrixX3d& warped_positions, const Eigen::MatrixX3d& warped_normals,
                           const ClosestPointIndex& target_index, double target_diagonal,
                           const ProjectionOptions& options, std::vector<std::uint64_t> region_masks) {
  ClosestPointOptions cp;
  cp.max_normal_angle_deg = options.max_normal_angle_deg;
  cp.max_distance = options.max_distance * target_diagonal;
  ClosestPointFilters filters;
  filters.normals = warped_normals;
  filters.label_masks = std::move(region_masks);
  GuideModel guide;
  guide.on_target = target_index.closestPoints(warped_positions, cp, filters);
  guide.positions = warped_positions;
  guide.distance = Eigen::VectorXd::Zero(warped_positions.rows());
  for (Eigen::Index v = 0; v < warped_positions.rows(); ++v) {
    const SurfacePoint& sp = guide.on_target[static_cast<std::size_t>(v)];
    if (!sp.found()) {
      ++guide.unmatched;
      continue;
    }
    guide.positions.row(v) = sp.point.transpose();
    guide.distance(v) = std::sqrt(sp.sq_distance);
  }
  return guide;
}

double faceOrientationAgreement(const Eigen::MatrixX3d& warped_points, const Eigen::MatrixX3d& warped_normals,
                                const ClosestPointIndex& target_index, const Mesh& target) {
  double sum = 0.0;
  int votes = 0;
  for (Eigen::Index v = 0; v < warped_points.rows(); ++v) {
    const SurfacePoint sp = target_index.closestPoint(warped_points.row(v).transpose());
    if (!sp.found()) continue;
    const Eigen::Vector3i t = target.triangles.row(sp.face);
    const Eigen::Vector3d a = target.positions.row(t(0)), b = target.positions.row(t(1)), c = target.positions.row(t(2));
    const double d = (b - a).cross(c - a).dot(warped_normals.row(v).transpose());
    if (d == 0.0 || !std::isfinite(d)) continue;  // no usable source normal (isolated vertex)
    sum += d > 0.0 ? 1.0 : -1.0;
    ++votes;
  }
  return votes > 0 ? sum / votes : 0.0;
}

FoldReport countFolds(const Eigen::MatrixX3d& warped_positions, const Eigen::MatrixX3d& guide_positions,
                      const Eigen::MatrixX3i& triangles) {
  FoldReport report;
  const double diag = boundingBoxDiagonal(warped_positions);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const Eigen::Vector3i t = triangles.row(f);
    if (isDegenerateTriangle(warped_positions, t, diag)) continue;
    if (isDegenerateTriangle(guide_positions, t, diag)) {
      ++report.collapsed;
      continue;
    }
    const Eigen::Vector3d a0 = warped_positions.row(t(0)), a1 = warped_positions.row(t(1)), a2 = warped_positions.row(t(2));
    const Eigen::Vector3d b0 = guide_positions.row(t(0)), b1 = guide_positions.row(t(1)), b2 = guide_positions.row(t(2));
    if ((a1 - a0).cross(a2 - a0).dot((b1 - b0).cross(b2 - b0)) < 0.0) {
      ++report.flipped;
      report.flipped_faces.push_back(static_cast<int>(f));
    }
  }
  return report;
}

TargetLocations locateOnGuide(const Mesh& target, const Eigen::MatrixX3d& guide_positions,
                              const MovingMeshIndex& guide_faces, const LocateOptions& options,
                              const std::vector<std::uint64_t>& source_face_labels,
                              const std::vector<std::uint64_t>& target_masks, const std::vector<int>& target_sides,
                              const std::vector<int>* target_representative) {
  const bool labelled = !source_face_labels.empty() && !target_masks.empty();
  const Eigen::MatrixX3i& source_triangles = guide_faces.triangles();
  const MovingMeshIndex::Fitted guide_index =
      guide_faces.fit(guide_positions, labelled ? source_face_labels : std::vector<std::uint64_t>());
  const Eigen::Index n = target.positions.rows();
  // The copies of a split point (UV seams, hard edges) are one point of the
  // surface: matched with one normal (their average where theirs differ) and
  // judged by the edges around the whole point, so that every copy gets the
  // same location, confidence and flags. Otherwise a copy judged apart (its
  // side's edges only, its side's normal) could be inpainted while its twin
  // keeps its value, and the seam would part when the mesh moves.
  std::vector<int> computed;
  if (!target_representative) computed = coincidentVertexRepresentatives(target.positions);
  const std::vector<int>& representative = target_representative ? *target_representative : computed;
  auto pointOf = [&](Eigen::Index v) -> Eigen::Index {
    return representative.empty() ? v : representative[static_cast<std::size_t>(v)];
  };
  Eigen::MatrixX3d normals =
      target.normals.rows() == target.positions.rows() ? target.normals
                                                        : computeSeamlessVertexNormals(target.positions, target.triangles);
  if (!representative.empty()) {
    std::vector<char> differs(static_cast<std::size_t>(n), 0);
    bool any = false;
    for (Eigen::Index v = 0; v < n; ++v) {
      const Eigen::Index r = pointOf(v);
      if (r != v && normals.row(v) != normals.row(r)) {
        differs[static_cast<std::size_t>(r)] = 1;
        any = true;
      }
    }
    if (any) {
      Eigen::MatrixX3d summed = Eigen::MatrixX3d::Zero(n, 3);
      for (Eigen::Index v = 0; v < n; ++v) {
        if (differs[static_cast<std::size_t>(pointOf(v))]) summed.row(pointOf(v)) += normals.row(v);
      }
      for (Eigen::Index v = 0; v < n; ++v) {
        const Eigen::Index r = pointOf(v);
        const double length = summed.row(r).norm();
        if (differs[static_cast<std::size_t>(r)] && length > 0.0) normals.row(v) = summed.row(r) / length;
      }
    }
  }
  ClosestPointOptions cp;
  cp.max_normal_angle_deg = options.max_normal_angle_deg;
  ClosestPointFilters filters;
  filters.normals = normals;
  if (labelled) filters.label_masks = target_masks;

  TargetLocations out;
  out.on_source = guide_index.closestPoints(target.positions, cp, filters);
  out.distance = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::infinity());
  out.normal_cosine = Eigen::VectorXd::Constant(n, -1.0);
  out.confidence = Eigen::VectorXd::Zero(n);
  out.mismatched = Eigen::VectorXi::Zero(n);

  // Smooth guide normals interpolated at the located point: a flat face normal
  // would disagree with a curved surface's vertex normal by a few degrees.
  const Eigen::MatrixX3d guide_normals = computeVertexNormals(guide_positions, source_triangles);
  const double max_distance = options.low_confidence_distance * boundingBoxDiagonal(target.positions);
  const Eigen::VectorXd edge = meanIncidentEdgeLengths(target, representative);
  const double cos_limit = std::cos(options.low_confidence_angle_deg * std::numbers::pi / 180.0);
  // Near an opening, a location whose normal disagrees may be the other lip
  // or lid, a hair away where they touch near a corner (the sides are not
  // sure there): one within an edge farther whose normal agrees is taken
  // instead.
  if (!target_sides.empty() && options.opening_normal_angle_deg < options.max_normal_angle_deg) {
    const double cos_opening = std::cos(options.opening_normal_angle_deg * std::numbers::pi / 180.0);
    std::vector<int> retry;
    for (Eigen::Index v = 0; v < n; ++v) {
      const SurfacePoint& sp = out.on_source[static_cast<std::size_t>(v)];
      if (!sp.found() || target_sides[static_cast<std::size_t>(v)] != kBetweenSides) continue;
      const Eigen::RowVector3d gn = interpolateOnFace(guide_normals, source_triangles, sp.face, sp.barycentric);
      const double len = gn.norm();
      if (!(len > 0.0 && gn.dot(normals.row(v)) / len >= cos_opening)) retry.push_back(static_cast<int>(v));
    }
    if (!retry.empty()) {
      ClosestPointOptions strict = cp;
      strict.max_normal_angle_deg = options.opening_normal_angle_deg;
      ClosestPointFilters again_filters;
      again_filters.normals.resize(static_cast<Eigen::Index>(retry.size()), 3);
      Eigen::MatrixX3d queries(static_cast<Eigen::Index>(retry.size()), 3);
      for (std::size_t i = 0; i < retry.size(); ++i) {
        queries.row(static_cast<Eigen::Index>(i)) = target.positions.row(retry[i]);
        again_filters.normals.row(static_cast<Eigen::Index>(i)) = normals.row(retry[i]);
        if (labelled) again_filters.label_masks.push_back(target_masks[static_cast<std::size_t>(retry[i])]);
      }
      const std::vector<SurfacePoint> again = guide_index.closestPoints(queries, strict, again_filters);
      for (std::size_t i = 0; i < retry.size(); ++i) {
        SurfacePoint& sp = out.on_source[static_cast<std::size_t>(retry[i])];
        if (!again[i].found() || std::sqrt(again[i].sq_distance) > std::sqrt(sp.sq_distance) + edge(retry[i])) continue;
        if (labelled && (source_face_labels[static_cast<std::size_t>(sp.face)] & source_face_labels[static_cast<std::size_t>(again[i].face)]) != 0) continue;
        sp = again[i];
      }
    }
  }
  for (Eigen::Index v = 0; v < n; ++v) {
    const SurfacePoint& sp = out.on_source[static_cast<std::size_t>(v)];
    if (!sp.found()) {
      ++out.low_confidence;
      out.mismatched(v) = 1;
      continue;
    }
    const double d = std::sqrt(sp.sq_distance);
    const Eigen::RowVector3d gn = interpolateOnFace(guide_normals, source_triangles, sp.face, sp.barycentric);
    const double len = gn.norm();
    const double c = len > 0.0 ? gn.dot(normals.row(v)) / len : -1.0;
    out.distance(v) = d;
    out.normal_cosine(v) = c;
    const double distance_term = max_distance > 0.0 ? std::max(0.0, 1.0 - d / max_distance) : (d == 0.0 ? 1.0 : 0.0);
    const double angle_term = cos_limit < 1.0 ? std::clamp((c - cos_limit) / (1.0 - cos_limit), 0.0, 1.0) : 1.0;
    const bool jumped = options.max_relative_distance > 0.0 && edge(v) > 0.0 && d > options.max_relative_distance * edge(v);
    out.confidence(v) = jumped ? 0.0 : distance_term * angle_term;
    out.mismatched(v) = jumped ? 1 : 0;
    if (d > max_distance || c < cos_limit || jumped) ++out.low_confidence;
  }
  return out;
}

namespace {

// One farthest-point step over a run of points: sq = min(sq, |x - p|^2), and the
// first index of the largest sq afterwards, in one pass. Written with GCC
// vector types (four lanes, each keeping its largest value and the first
// index where it occurs; comparisons are exact, so the answer does not depend
// on the lane layout): GCC does not vectorise this reduction on its own.
RIGPORT_VECTOR_CLONES
std::ptrdiff_t nearestSampleUpdate(const double* x, const double* y, const double* z, double* sq, std::ptrdiff_t n,
                                   double px, double py, double pz) {
  typedef double Lanes __attribute__((vector_size(32)));
  typedef long long Indices __attribute__((vector_size(32)));
  Lanes largest = {-1.0, -1.0, -1.0, -1.0};
  Indices at = {0, 0, 0, 0};
  Indices lane = {0, 1, 2, 3};
  std::ptrdiff_t v = 0;
  for (; v + 4 <= n; v += 4, lane += 4) {
    Lanes a, b, c, old;
    std::memcpy(&a, x + v, sizeof a);
    std::memcpy(&b, y + v, sizeof b);
    std::memcpy(&c, z + v, sizeof c);
    std::memcpy(&old, sq + v, sizeof old);
    const Lanes dx = a - px, dy = b - py, dz = c - pz;
    const Lanes d = dx * dx + dy * dy + dz * dz;
    const Lanes nearest = d < old ? d : old;
    std::memcpy(sq + v, &nearest, sizeof nearest);
    const Indices larger = nearest > largest;
    largest = larger ? nearest : largest;
    at = larger ? lane : at;
  }
  double best = -1.0;
  std::ptrdiff_t best_at = 0;
  for (int k = 0; k < 4; ++k) {
    if (largest[k] > best || (largest[k] == best && at[k] < best_at)) {
      best = largest[k];
      best_at = at[k];
    }
  }
  for (; v < n; ++v) {
    const double dx = x[v] - px, dy = y[v] - py, dz = z[v] - pz;
    sq[v] = std::min(sq[v], dx * dx + dy * dy + dz * dz);
    if (sq[v] > best) {
      best = sq[v];
      best_at = v;
    }
  }
  return best_at;
}

}  // namespace

namespace {

// out = b * y for a square column-major b (m by m) and m-by-3 y, out: one
// pass over b, column by column (three axpys per column, which GCC
// vectorises; Eigen's product repacked b on every call, ~40% of the time).
// Each output lane sums in a fixed order: the same result on every machine.
// Inlined into each clone below, so that every target vectorises it.
template <class Scalar>
[[gnu::always_inline]] inline void timesPointsBody(const Scalar* __restrict b, std::ptrdiff_t m, const Scalar* __restrict y,
                                                   Scalar* __restrict out) {
  std::fill(out, out + 3 * m, Scalar{0});
  Scalar* out_x = out;
  Scalar* out_y = out + m;
  Scalar* out_z = out + 2 * m;
  // Four columns per pass over the outputs (a quarter of their loads and
  // stores); each output still adds the columns' terms one at a time, in
  // column order, so the sums are those of one column per pass.
  std::ptrdiff_t j = 0;
  for (; j + 4 <= m; j += 4) {
    const Scalar* c0 = b + j * m;
    const Scalar* c1 = c0 + m;
    const Scalar* c2 = c1 + m;
    const Scalar* c3 = c2 + m;
    const Scalar x0 = y[j], x1 = y[j + 1], x2 = y[j + 2], x3 = y[j + 3];
    const Scalar y0 = y[m + j], y1 = y[m + j + 1], y2 = y[m + j + 2], y3 = y[m + j + 3];
    const Scalar z0 = y[2 * m + j], z1 = y[2 * m + j + 1], z2 = y[2 * m + j + 2], z3 = y[2 * m + j + 3];
    for (std::ptrdiff_t i = 0; i < m; ++i) {
      out_x[i] = (((out_x[i] + x0 * c0[i]) + x1 * c1[i]) + x2 * c2[i]) + x3 * c3[i];
      out_y[i] = (((out_y[i] + y0 * c0[i]) + y1 * c1[i]) + y2 * c2[i]) + y3 * c3[i];
      out_z[i] = (((out_z[i] + z0 * c0[i]) + z1 * c1[i]) + z2 * c2[i]) + z3 * c3[i];
    }
  }
  for (; j < m; ++j) {
    const Scalar* column = b + j * m;
    const Scalar yx = y[j], yy = y[m + j], yz = y[2 * m + j];
    for (std::ptrdiff_t i = 0; i < m; ++i) {
      out_x[i] += yx * column[i];
      out_y[i] += yy * column[i];
      out_z[i] += yz * column[i];
    }
  }
}

RIGPORT_VECTOR_CLONES
void timesPoints(const double* b, std::ptrdiff_t m, const double* y, double* out) { timesPointsBody(b, m, y, out); }

// In float for the conjugate-gradient products of the sliding block: half the
// bytes streamed per product (the ICT rig's 465 x 465 block fits the 1 MB L2
// in float, not in double).
RIGPORT_VECTOR_CLONES
void timesPoints(const float* b, std::ptrdiff_t m, const float* y, float* out) { timesPointsBody(b, m, y, out); }

}  // namespace

Eigen::MatrixX3d slideInTangentPlanes(const Eigen::MatrixXd& bending, const Eigen::MatrixX3d& targets,
                                      const std::vector<int>& sliding, const Eigen::MatrixX3d& normals,
                                      int iterations) {
  const auto m = static_cast<Eigen::Index>(sliding.size());
  Eigen::MatrixX3d moved = targets;
  if (m == 0) return moved;
  // Two tangent directions per sliding point; unknowns t (2 per point):
  // minimise tr((Y + S T t)^T B (Y + S T t)), i.e. solve
  // (T^T B_ss T) t = -T^T (B Y)_s, positive semidefinite.
  std::vector<Eigen::Matrix<double, 3, 2>> tangent(static_cast<std::size_t>(m));
  Eigen::MatrixXf b_ss(m, m);
  for (Eigen::Index i = 0; i < m; ++i) {
    const double length = normals.row(i).norm();
    if (length > 0.0 && std::isfinite(length)) {
      const Eigen::Vector3d n = normals.row(i).transpose() / length;
      const Eigen::Vector3d u = n.unitOrthogonal();
      tangent[static_cast<std::size_t>(i)] << u, n.cross(u);
    } else {
      tangent[static_cast<std::size_t>(i)].setZero();  // no plane to slide in: the point stays
    }
  }
  // Column by column: both matrices are column-major.
  for (Eigen::Index j = 0; j < m; ++j) {
    const double* column = bending.col(sliding[static_cast<std::size_t>(j)]).data();
    for (Eigen::Index i = 0; i < m; ++i) b_ss(i, j) = static_cast<float>(column[sliding[static_cast<std::size_t>(i)]]);
  }
  auto toPoints = [&](const Eigen::VectorXd& t) {
    Eigen::MatrixX3d d(m, 3);
    for (Eigen::Index i = 0; i < m; ++i) d.row(i) = (tangent[static_cast<std::size_t>(i)] * t.segment<2>(2 * i)).transpose();
    return d;
  };
  auto toTangents = [&](const Eigen::MatrixX3d& d) {
    Eigen::VectorXd t(2 * m);
    for (Eigen::Index i = 0; i < m; ++i) t.segment<2>(2 * i) = tangent[static_cast<std::size_t>(i)].transpose() * d.row(i).transpose();
    return t;
  };
  Eigen::MatrixX3d by(targets.rows(), 3);
  timesPoints(bending.data(), targets.rows(), targets.data(), by.data());
  Eigen::MatrixX3d by_s(m, 3);
  for (Eigen::Index i = 0; i < m; ++i) by_s.row(i) = by.row(sliding[static_cast<std::size_t>(i)]);
  // Preconditioned by the diagonal (B_ii for both directions of point i).
  Eigen::VectorXd inverse_diagonal(2 * m);
  for (Eigen::Index i = 0; i < m; ++i) {
    const auto v = static_cast<Eigen::Index>(sliding[static_cast<std::size_t>(i)]);
    inverse_diagonal.segment<2>(2 * i).setConstant(bending(v, v) > 0.0 ? 1.0 / bending(v, v) : 0.0);
  }
  Eigen::VectorXd t = Eigen::VectorXd::Zero(2 * m);
  Eigen::VectorXd residual = -toTangents(by_s);
  Eigen::VectorXd z = inverse_diagonal.cwiseProduct(residual);
  Eigen::VectorXd direction = z;
  double rz = residual.dot(z);
  const double stop = 1e-16 * rz;
  Eigen::MatrixX3f b_points(m, 3);
  for (int k = 0; k < iterations && rz > stop; ++k) {
    const Eigen::MatrixX3f points = toPoints(direction).cast<float>();
    timesPoints(b_ss.data(), m, points.data(), b_points.data());
    const Eigen::VectorXd a_direction = toTangents(b_points.cast<double>());
    const double curvature = direction.dot(a_direction);
    if (!(curvature > 0.0)) break;
    const double alpha = rz / curvature;
    t += alpha * direction;
    residual -= alpha * a_direction;
    z = inverse_diagonal.cwiseProduct(residual);
    const double rz_next = residual.dot(z);
    direction = z + (rz_next / rz) * direction;
    rz = rz_next;
  }
  const Eigen::MatrixX3d step = toPoints(t);
  for (Eigen::Index i = 0; i < m; ++i) moved.row(sliding[static_cast<std::size_t>(i)]) += step.row(i);
  return moved;
}

namespace {

// A candidate for the next farthest point: the larger squared distance wins,
// then the lower vertex index (the first of equal maxima in vertex order).
struct FarthestCandidate {
  double sq = -1.0;
  std::ptrdiff_t vertex = -1;
  bool beats(const FarthestCandidate& other) const {
    return sq > other.sq || (sq == other.sq && vertex >= 0 && (other.vertex < 0 || vertex < other.vertex));
  }
};

}  // namespace

// Exact farthest-point sampling with the points bucketed in a uniform grid:
// a new sample p can only lower sq[v] for points nearer p than the current
// largest distance R (every sq[v] <= R^2), so only grid cells whose points'
// box comes within R are visited (late samples touch a few cells, not all
// points). A cell is skipped only when the squared distance from p to its
// points' box exceeds R^2; that distance is computed with the same operations
// as a point's and rounding is monotonic, so no skipped point could have
// changed: the sample is the one of the plain O(n k) loop, ties included.
// The largest sq is kept per cell and over cells in a tournament tree.
std::vector<int> farthestPointSample(const Eigen::MatrixX3d& positions, int count) {
  const Eigen::Index n = positions.rows();
  std::vector<int> chosen;
  if (n == 0 || count <= 0) return chosen;
  count = static_cast<int>(std::min<Eigen::Index>(count, n));
  const Eigen::RowVector3d centroid = positions.colwise().mean();
  Eigen::Index first = 0;
  (positions.rowwise() - centroid).rowwise().squaredNorm().minCoeff(&first);

  // Grid of about n / 32 cells over the bounding box (at most 64 per axis):
  // enough points per cell for the vectorised update to pay.
  const Eigen::Array3d lo = positions.colwise().minCoeff().transpose().array();
  const Eigen::Array3d extent = (positions.colwise().maxCoeff().transpose().array() - lo).cwiseMax(0.0);
  const double volume = std::max(extent.prod(), 1e-300);
  double cell = std::cbrt(32.0 * volume / static_cast<double>(n));
  if (!(cell > 0.0) || !std::isfinite(cell)) cell = std::max(extent.maxCoeff(), 1.0);
  Eigen::Array3i dims;
  for (int a = 0; a < 3; ++a) {
    dims(a) = std::clamp(static_cast<int>(extent(a) / cell) + 1, 1, 64);
  }
  const Eigen::Array3d inverse_size = dims.cast<double>() / extent.cwiseMax(1e-300);
  auto axisCell = [&](double coordinate, int a) {
    const double at = (coordinate - lo(a)) * inverse_size(a);
    if (!(at > 0.0)) return 0;
    return at >= dims(a) - 1 ? dims(a) - 1 : static_cast<int>(at);
  };
  const std::size_t cells = static_cast<std::size_t>(dims.prod());
  std::vector<int> cell_of(static_cast<std::size_t>(n));
  std::vector<int> start(cells + 1, 0);
  for (Eigen::Index v = 0; v < n; ++v) {
    const int c = axisCell(positions(v, 0), 0) + dims(0) * (axisCell(positions(v, 1), 1) + dims(1) * axisCell(positions(v, 2), 2));
    cell_of[static_cast<std::size_t>(v)] = c;
    ++start[static_cast<std::size_t>(c) + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) start[c + 1] += start[c];
  // Points in cell order, each cell's in vertex order; the cell's box.
  std::vector<std::ptrdiff_t> vertex(static_cast<std::size_t>(n));
  std::vector<double> x(static_cast<std::size_t>(n)), y(x.size()), z(x.size());
  std::vector<double> sq(x.size(), std::numeric_limits<double>::infinity());
  std::vector<Eigen::Array3d> box_lo(cells, Eigen::Array3d::Constant(std::numeric_limits<double>::infinity()));
  std::vector<Eigen::Array3d> box_hi(cells, Eigen::Array3d::Constant(-std::numeric_limits<double>::infinity()));
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (Eigen::Index v = 0; v < n; ++v) {
      const auto c = static_cast<std::size_t>(cell_of[static_cast<std::size_t>(v)]);
      const auto at = static_cast<std::size_t>(fill[c]++);
      vertex[at] = v;
      x[at] = positions(v, 0);
      y[at] = positions(v, 1);
      z[at] = positions(v, 2);
      box_lo[c] = box_lo[c].min(positions.row(v).transpose().array());
      box_hi[c] = box_hi[c].max(positions.row(v).transpose().array());
    }
  }
  std::size_t leaves = 1;
  while (leaves < cells) leaves *= 2;
  std::vector<FarthestCandidate> tree(2 * leaves);
  auto better = [](const FarthestCandidate& a, const FarthestCandidate& b) { return a.beats(b) ? a : b; };

  std::vector<std::size_t> touched;
  Eigen::Index next = first;
  double reach = std::numeric_limits<double>::infinity();  // squared: the largest sq before this step
  for (int k = 0; k < count; ++k) {
    chosen.push_back(static_cast<int>(next));
    const double px = positions(next, 0), py = positions(next, 1), pz = positions(next, 2);
    const double radius = std::sqrt(reach);
    Eigen::Array3i from, to;
    for (int a = 0; a < 3; ++a) {
      const double p = positions(next, a);
      from(a) = std::isfinite(radius) ? axisCell(p - radius, a) : 0;
      to(a) = std::isfinite(radius) ? axisCell(p + radius, a) : dims(a) - 1;
    }
    for (int cz = from(2); cz <= to(2); ++cz) {
      for (int cy = from(1); cy <= to(1); ++cy) {
        for (int cx = from(0); cx <= to(0); ++cx) {
          const auto c = static_cast<std::size_t>(cx + dims(0) * (cy + dims(1) * cz));
          if (start[c] == start[c + 1]) continue;
          const double gx = std::max({box_lo[c](0) - px, 0.0, px - box_hi[c](0)});
          const double gy = std::max({box_lo[c](1) - py, 0.0, py - box_hi[c](1)});
          const double gz = std::max({box_lo[c](2) - pz, 0.0, pz - box_hi[c](2)});
          if (gx * gx + gy * gy + gz * gz > reach) continue;
          // The cell's points are in vertex order: its first largest is the lowest vertex.
          const std::ptrdiff_t at = start[c];
          const std::ptrdiff_t largest =
              at + nearestSampleUpdate(x.data() + at, y.data() + at, z.data() + at, sq.data() + at, start[c + 1] - at, px, py, pz);
          tree[leaves + c] = {sq[static_cast<std::size_t>(largest)], vertex[static_cast<std::size_t>(largest)]};
          touched.push_back(leaves + c);
        }
      }
    }
    // Cells were visited in increasing order, so each level's parents come
    // sorted: shared ancestors are recomputed once.
    while (!touched.empty() && touched.front() > 1) {
      std::size_t kept = 0;
      for (std::size_t node : touched) {
        const std::size_t parent = node / 2;
        if (kept > 0 && touched[kept - 1] == parent) continue;
        tree[parent] = better(tree[2 * parent], tree[2 * parent + 1]);
        touched[kept++] = parent;
      }
      touched.resize(kept);
    }
    touched.clear();
    reach = tree[1].sq;
    next = tree[1].vertex;
  }
  return chosen;
}

}  // namespace core
