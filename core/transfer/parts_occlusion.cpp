// SkinOcclusion: see parts_occlusion.h. Every line runs along one direction,
// so a 2D grid over the triangles projected along it is the whole spatial
// index: a line is a point of the view plane, its crossings the triangles
// whose projection covers that point.
#include "core/transfer/parts_occlusion.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <Eigen/Eigenvalues>

namespace core {

Eigen::Vector3d faceForward(const Eigen::MatrixX3d& landmark_positions, const Eigen::Vector3d& toward) {
  if (landmark_positions.rows() < 3) return Eigen::Vector3d::Zero();
  const Eigen::RowVector3d centroid = landmark_positions.colwise().mean();
  const Eigen::MatrixX3d centred = landmark_positions.rowwise() - centroid;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred.transpose() * centred);
  // A plane needs two spread directions (eigenvalues ascending).
  if (!(eig.eigenvalues()(1) > 1e-12 * eig.eigenvalues()(2))) return Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = eig.eigenvectors().col(0).normalized();
  return normal.dot(toward) < 0.0 ? Eigen::Vector3d(-normal) : normal;
}

namespace {

// A triangle as seen along forward: its corners in the view plane, their
// depths along forward, and the inverse of its projected twice-area.
struct ViewTriangle {
  Eigen::Vector2d a, b, c;
  Eigen::Vector3d depth;
  double front = 0.0;  // the largest depth
  double inverse_area = 0.0;
  bool cap = false;
};

// The triangles over a region of the view plane, in a grid of cells each
// listing the triangles whose bounding box meets it, front-most first.
class ViewGrid {
 public:
  ViewGrid(std::vector<ViewTriangle> triangles, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi);

  struct Crossing {
    bool found = false;
    bool cap = false;
    double depth = -std::numeric_limits<double>::infinity();
  };
  // The front-most crossing of the line through view point x (in the region).
  Crossing front(const Eigen::Vector2d& x) const;

 private:
  std::vector<ViewTriangle> view_;
  Eigen::Vector2d origin_;
  double cell_ = 1.0;
  int columns_ = 0, rows_ = 0;
  std::vector<int> offsets_, entries_;
};

ViewGrid::ViewGrid(std::vector<ViewTriangle> triangles, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi)
    : view_(std::move(triangles)), origin_(lo) {
  offsets_.assign(1, 0);
  if (view_.empty()) return;
  // Front-most first: a line's search ends at the first triangle wholly
  // behind the best crossing found.
  std::vector<std::pair<double, int>> order(view_.size());
  for (std::size_t i = 0; i < view_.size(); ++i) order[i] = {-view_[i].front, static_cast<int>(i)};
  std::sort(order.begin(), order.end());
  std::vector<ViewTriangle> sorted(view_.size());
  for (std::size_t i = 0; i < view_.size(); ++i) sorted[i] = view_[static_cast<std::size_t>(order[i].second)];
  view_ = std::move(sorted);
  // About one triangle per cell.
  const Eigen::Vector2d extent = (hi - lo).cwiseMax(1e-9 * std::max(1.0, (hi - lo).norm()));
  cell_ = std::sqrt(extent.x() * extent.y() / static_cast<double>(view_.size()));
  columns_ = std::clamp(static_cast<int>(std::ceil(extent.x() / cell_)), 1, 1024);
  rows_ = std::clamp(static_cast<int>(std::ceil(extent.y() / cell_)), 1, 1024);
  cell_ = std::max(extent.x() / columns_, extent.y() / rows_);
  auto forEachCell = [&](const ViewTriangle& t, auto&& visit) {
    const Eigen::Vector2d tlo = (t.a.cwiseMin(t.b).cwiseMin(t.c) - origin_) / cell_;
    const Eigen::Vector2d thi = (t.a.cwiseMax(t.b).cwiseMax(t.c) - origin_) / cell_;
    const int c0 = std::clamp(static_cast<int>(std::floor(tlo.x())), 0, columns_ - 1);
    const int c1 = std::clamp(static_cast<int>(std::floor(thi.x())), 0, columns_ - 1);
    const int r0 = std::clamp(static_cast<int>(std::floor(tlo.y())), 0, rows_ - 1);
    const int r1 = std::clamp(static_cast<int>(std::floor(thi.y())), 0, rows_ - 1);
    for (int r = r0; r <= r1; ++r) {
      for (int c = c0; c <= c1; ++c) visit(static_cast<std::size_t>(r) * static_cast<std::size_t>(columns_) + static_cast<std::size_t>(c));
    }
  };
  std::vector<int> count(static_cast<std::size_t>(columns_) * static_cast<std::size_t>(rows_) + 1, 0);
  for (const ViewTriangle& t : view_) forEachCell(t, [&](std::size_t at) { ++count[at + 1]; });
  for (std::size_t i = 1; i < count.size(); ++i) count[i] += count[i - 1];
  offsets_ = count;
  entries_.resize(static_cast<std::size_t>(offsets_.back()));
  for (std::size_t i = 0; i < view_.size(); ++i) {
    forEachCell(view_[i], [&](std::size_t at) { entries_[static_cast<std::size_t>(count[at]++)] = static_cast<int>(i); });
  }
}

ViewGrid::Crossing ViewGrid::front(const Eigen::Vector2d& x) const {
  Crossing out;
  if (columns_ == 0) return out;
  const Eigen::Vector2d g = (x - origin_) / cell_;
  const int c = std::clamp(static_cast<int>(std::floor(g.x())), 0, columns_ - 1);
  const int r = std::clamp(static_cast<int>(std::floor(g.y())), 0, rows_ - 1);
  constexpr double kEdge = 1e-9;  // a line along a shared edge meets both triangles: neither is missed
  const std::size_t at = static_cast<std::size_t>(r) * static_cast<std::size_t>(columns_) + static_cast<std::size_t>(c);
  for (int k = offsets_[at]; k < offsets_[at + 1]; ++k) {
    const ViewTriangle& t = view_[static_cast<std::size_t>(entries_[static_cast<std::size_t>(k)])];
    if (out.found && t.front < out.depth) break;
    const Eigen::Vector2d e1 = t.b - t.a, e2 = t.c - t.a, d = x - t.a;
    const double u = (d.x() * e2.y() - d.y() * e2.x()) * t.inverse_area;
    const double v = (e1.x() * d.y() - e1.y() * d.x()) * t.inverse_area;
    if (u < -kEdge || v < -kEdge || u + v > 1.0 + kEdge) continue;
    const double depth = (1.0 - u - v) * t.depth(0) + u * t.depth(1) + v * t.depth(2);
    // Ties (a rim vertex, where cap and skin meet) go to the skin.
    if (!out.found || depth > out.depth || (depth == out.depth && !t.cap)) {
      out.found = true;
      out.depth = depth;
      out.cap = t.cap;
    }
  }
  return out;
}

}  // namespace

SkinOcclusion::SkinOcclusion(const Mesh& face, const Eigen::Vector3d& forward, const OcclusionOptions& options)
    : forward_(forward.normalized()), triangles_(face.triangles) {
  // Any axis not along forward spans the view plane with it.
  const Eigen::Vector3d helper = std::abs(forward_.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d up = forward_.cross(helper).normalized();
  axes_.col(0) = up.cross(forward_);
  axes_.col(1) = up;
  axes_.col(2) = forward_;
  tolerance_ = options.tolerance * boundingBoxDiagonal(face.positions);
  // Openings on the welded topology: a UV seam is no boundary.
  Mesh topology;
  topology.positions = face.positions;
  topology.triangles = face.triangles;
  for (const BoundaryLoop& loop : boundaryLoops(weldedTopology(topology, coincidentVertexRepresentatives(face.positions)))) {
    if (loop.closed && loop.vertices.size() >= 3) loops_.push_back(loop.vertices);
  }
}

Eigen::VectorXd SkinOcclusion::standOut(const Eigen::MatrixX3d& face_positions, const Eigen::MatrixX3d& points) const {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(points.rows());
  if (points.rows() == 0) return out;
  const Eigen::MatrixX3d seen = face_positions * axes_;  // (across, up, forward) per face vertex
  const Eigen::MatrixX3d asked = points * axes_;
  // Only triangles over the points' region of the view plane can cross their lines.
  const Eigen::Vector2d lo = asked.leftCols<2>().colwise().minCoeff().transpose();
  const Eigen::Vector2d hi = asked.leftCols<2>().colwise().maxCoeff().transpose();
  const double diagonal = boundingBoxDiagonal(face_positions);
  const double min_area = 1e-14 * diagonal * diagonal;
  std::vector<ViewTriangle> view;
  auto add = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Vector3d& r, bool cap) {
    ViewTriangle t;
    t.a = p.head<2>();
    t.b = q.head<2>();
    t.c = r.head<2>();
    if ((t.a.cwiseMax(t.b).cwiseMax(t.c).array() < lo.array()).any() || (t.a.cwiseMin(t.b).cwiseMin(t.c).array() > hi.array()).any()) return;
    const Eigen::Vector2d e1 = t.b - t.a, e2 = t.c - t.a;
    const double area = e1.x() * e2.y() - e1.y() * e2.x();
    // Seen edge-on a triangle is crossed by no line its neighbours miss.
    if (!(std::abs(area) > min_area)) return;
    t.inverse_area = 1.0 / area;
    t.depth = {p.z(), q.z(), r.z()};
    t.front = t.depth.maxCoeff();
    t.cap = cap;
    view.push_back(t);
  };
  for (Eigen::Index f = 0; f < triangles_.rows(); ++f) {
    const Eigen::Vector3i t = triangles_.row(f).transpose();
    if (t(0) == t(1) || t(1) == t(2) || t(0) == t(2)) continue;
    add(seen.row(t(0)).transpose(), seen.row(t(1)).transpose(), seen.row(t(2)).transpose(), false);
  }
  // Each opening closed by a fan about its rim's centroid.
  for (const std::vector<int>& loop : loops_) {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int v : loop) centre += seen.row(v).transpose();
    centre /= static_cast<double>(loop.size());
    for (std::size_t i = 0; i < loop.size(); ++i) {
      add(centre, seen.row(loop[i]).transpose(), seen.row(loop[(i + 1) % loop.size()]).transpose(), true);
    }
  }
  const ViewGrid grid(std::move(view), lo, hi);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const ViewGrid::Crossing crossing = grid.front(asked.row(i).head<2>().transpose());
    if (crossing.found && !crossing.cap) out(i) = asked(i, 2) - crossing.depth;
  }
  return out;
}

int SkinOcclusion::countInFront(const Eigen::VectorXd& stand_out) const {
  return static_cast<int>((stand_out.array() > tolerance_).count());
}

std::vector<int> partsInFront(const SkinOcclusion& skin, const Eigen::MatrixX3d& face_positions,
                              const std::vector<const Eigen::MatrixX3d*>& parts) {
  Eigen::Index rows = 0;
  for (const Eigen::MatrixX3d* p : parts) rows += p->rows();
  Eigen::MatrixX3d all(rows, 3);
  rows = 0;
  for (const Eigen::MatrixX3d* p : parts) {
    all.middleRows(rows, p->rows()) = *p;
    rows += p->rows();
  }
  const Eigen::VectorXd stand_out = skin.standOut(face_positions, all);
  std::vector<int> out;
  rows = 0;
  for (const Eigen::MatrixX3d* p : parts) {
    out.push_back(skin.countInFront(stand_out.segment(rows, p->rows())));
    rows += p->rows();
  }
  return out;
}

namespace {

std::vector<int> countsInFront(const Mesh& face, const Eigen::Vector3d& forward, const std::vector<RigPart>& parts,
                               const OcclusionOptions& options) {
  const SkinOcclusion skin(face, forward, options);
  std::vector<const Eigen::MatrixX3d*> positions;
  for (const RigPart& part : parts) positions.push_back(&part.mesh.positions);
  return partsInFront(skin, face.positions, positions);
}

}  // namespace

SourcePartsOcclusion prepareSourcePartsOcclusion(const Mesh& face, const Eigen::MatrixX3d& landmark_positions,
                                                 const std::vector<int>& landmark_vertices,
                                                 const std::vector<RigPart>& parts, const OcclusionOptions& options) {
  SourcePartsOcclusion out;
  if (parts.empty()) return out;
  Eigen::Vector3d toward = Eigen::Vector3d::Zero();
  for (const int v : landmark_vertices) {
    if (v >= 0 && v < face.normals.rows()) toward += face.normals.row(v).transpose();
  }
  out.forward = faceForward(landmark_positions, toward);
  if (out.forward.norm() > 0.0) out.in_front = countsInFront(face, out.forward, parts, options);
  return out;
}

std::vector<std::string> checkPartsBehindSkin(const SourcePartsOcclusion& source_check,
                                              const std::vector<RigPart>& source_parts, const Mesh& target_face,
                                              const Eigen::MatrixX3d& target_landmark_positions,
                                              const Eigen::Matrix3d& rotation, CarriedParts& carried,
                                              const OcclusionOptions& options) {
  std::vector<std::string> warnings;
  if (source_parts.empty() || source_check.in_front.size() != source_parts.size()) return warnings;
  const Eigen::Vector3d target_forward = faceForward(target_landmark_positions, rotation * source_check.forward);
  if (!(target_forward.norm() > 0.0)) return warnings;
  const std::vector<int>& source = source_check.in_front;
  const std::vector<int> target = countsInFront(target_face, target_forward, carried.parts, options);
  for (std::size_t p = 0; p < carried.report.size() && p < source.size(); ++p) {
    CarriedPart& report = carried.report[p];
    report.source_vertices_in_front = source[p];
    report.vertices_in_front = target[p];
    // Lashes stand in front by design: only what the rig hides is judged.
    const bool inner = 100 * source[p] <= source_parts[p].mesh.vertexCount();
    if (inner && target[p] > source[p]) {
      warnings.push_back("part " + report.name + " pokes through the face at rest: " + std::to_string(target[p]) + " of " +
                         std::to_string(carried.parts[p].mesh.vertexCount()) + " vertices in front of the skin (the rig: " +
                         std::to_string(source[p]) + ")");
    }
  }
  return warnings;
}

}  // namespace core
