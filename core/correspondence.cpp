// Dense correspondence by closest-point projection ("Stick", papers 004 eq. 4)
// and the inverse location of target vertices on the guide.
#include "core/correspondence.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

#include "core/vector_clones.h"

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
  cp.threads = options.threads;
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
    if ((a1 - a0).cross(a2 - a0).dot((b1 - b0).cross(b2 - b0)) < 0.0) ++report.flipped;
  }
  return report;
}

TargetLocations locateOnGuide(const Mesh& target, const Eigen::MatrixX3d& guide_positions,
                              const MovingMeshIndex& guide_faces, const LocateOptions& options,
                              const std::vector<std::uint64_t>& source_face_regions) {
  const bool by_region = !source_face_regions.empty();
  const Eigen::MatrixX3i& source_triangles = guide_faces.triangles();
  const MovingMeshIndex::Fitted guide_index = guide_faces.fit(guide_positions, source_face_regions);
  const Eigen::Index n = target.positions.rows();
  // The copies of a split point (UV seams, hard edges) are one point of the
  // surface: matched with one normal (their average where theirs differ) and
  // judged by the edges around the whole point, so that every copy gets the
  // same location, confidence and flags. Otherwise a copy judged apart (its
  // side's edges only, its side's normal) could be inpainted while its twin
  // keeps its value, and the seam would part when the mesh moves.
  const std::vector<int> representative = coincidentVertexRepresentatives(target.positions);
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
  cp.threads = options.threads;
  ClosestPointFilters filters;
  filters.normals = normals;
  if (by_region) filters.label_masks = vertexRegionBits(target.regions);

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

// One farthest-point step over all points: sq = min(sq, |x - p|^2), and the
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
[[gnu::always_inline]] inline void timesPointsBody(const Scalar* b, std::ptrdiff_t m, const Scalar* y, Scalar* out) {
  std::fill(out, out + 3 * m, Scalar{0});
  Scalar* out_x = out;
  Scalar* out_y = out + m;
  Scalar* out_z = out + 2 * m;
  for (std::ptrdiff_t j = 0; j < m; ++j) {
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
    for (Eigen::Index j = 0; j < m; ++j) {
      b_ss(i, j) = static_cast<float>(bending(sliding[static_cast<std::size_t>(i)], sliding[static_cast<std::size_t>(j)]));
    }
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

std::vector<int> farthestPointSample(const Eigen::MatrixX3d& positions, int count) {
  const Eigen::Index n = positions.rows();
  std::vector<int> chosen;
  if (n == 0 || count <= 0) return chosen;
  count = static_cast<int>(std::min<Eigen::Index>(count, n));
  const Eigen::RowVector3d centroid = positions.colwise().mean();
  Eigen::Index first = 0;
  (positions.rowwise() - centroid).rowwise().squaredNorm().minCoeff(&first);
  std::vector<double> sq(static_cast<std::size_t>(n), std::numeric_limits<double>::infinity());
  const double* x = positions.col(0).data();
  const double* y = positions.col(1).data();
  const double* z = positions.col(2).data();
  Eigen::Index next = first;
  for (int k = 0; k < count; ++k) {
    chosen.push_back(static_cast<int>(next));
    next = nearestSampleUpdate(x, y, z, sq.data(), n, x[next], y[next], z[next]);  // lowest index among ties
  }
  return chosen;
}

}  // namespace core
