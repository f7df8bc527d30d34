// Inputs the fit's tests and benchmark share: the ICT reference prepared once
// per process, scans made from a mesh (its exact 1-to-4 subdivision, a point
// cloud sampled on it, a similarity applied to it and its landmarks), and
// landmarks as positions.
#pragma once

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "core/fit/fit.h"
#include "core/geometry/mesh.h"
#include "core/geometry/similarity.h"
#include "core/io/landmarks.h"
#include "core/io/rig_io.h"
#include "core/synthetic/synthetic_rig.h"
#include "core/transfer/transfer.h"

namespace rigport_test {

// The ICT reference (source_face_skinned.glb + source_face.landmarks.json)
// prepared for fitting. `error` says why it did not load.
struct FitReferenceCase {
  std::shared_ptr<const core::PreparedRig> rig;
  std::shared_ptr<const core::FitReference> reference;
  std::string error;
};

// A rig prepared (or its error) made ready for fitting.
inline FitReferenceCase preparedForFitting(core::Result<core::PreparedRig> prepared) {
  FitReferenceCase out;
  if (!prepared) {
    out.error = prepared.error().message;
    return out;
  }
  out.rig = std::make_shared<const core::PreparedRig>(std::move(*prepared));
  auto reference = core::prepareFitReference(out.rig);
  if (!reference) {
    out.error = reference.error().message;
    return out;
  }
  out.reference = std::make_shared<const core::FitReference>(std::move(*reference));
  return out;
}

inline FitReferenceCase loadIctFitReference(const std::filesystem::path& data,
                                            const std::string& file = "source_face_skinned.glb") {
  FitReferenceCase out;
  auto rig = core::readRig(data / "ict" / file);
  if (!rig) {
    out.error = rig.error().message;
    return out;
  }
  auto landmarks = core::readLandmarks(data / "ict" / "source_face.landmarks.json");
  if (!landmarks) {
    out.error = landmarks.error().message;
    return out;
  }
  return preparedForFitting(core::prepareRig(std::move(rig->rig), std::move(*landmarks), file));
}

// Loaded once per process (the first caller's data directory).
inline const FitReferenceCase& ictFitReference(const std::filesystem::path& data) {
  static const FitReferenceCase loaded = loadIctFitReference(data);
  return loaded;
}

// The generated rig (core/synthetic, metres; skin, 6 shapes, a clip)
// prepared for fitting, once per process: the data-free reference.
inline const FitReferenceCase& syntheticFitReference() {
  static const FitReferenceCase loaded = [] {
    core::SyntheticRig generated = core::generateRig();
    return preparedForFitting(core::prepareRig(std::move(generated.rig), std::move(generated.landmarks), "synthetic rig"));
  }();
  return loaded;
}

// Each triangle split into four at its edge midpoints (shared midpoints
// merged): the surface is exactly the same, the vertex count about four
// times. Positions only (a scan's normals are computed by prepareScan).
inline core::Mesh subdivideMidpoints(const core::Mesh& mesh) {
  std::map<std::pair<int, int>, int> midpoint;
  std::vector<Eigen::RowVector3d> positions;
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) positions.push_back(mesh.positions.row(v));
  auto mid = [&](int a, int b) {
    const auto key = std::minmax(a, b);
    auto [it, added] = midpoint.try_emplace({key.first, key.second}, static_cast<int>(positions.size()));
    if (added) positions.push_back(0.5 * (mesh.positions.row(a) + mesh.positions.row(b)));
    return it->second;
  };
  core::Mesh out;
  out.triangles.resize(4 * mesh.triangleCount(), 3);
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    const int a = mesh.triangles(f, 0), b = mesh.triangles(f, 1), c = mesh.triangles(f, 2);
    const int ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
    out.triangles.row(4 * f) << a, ab, ca;
    out.triangles.row(4 * f + 1) << ab, b, bc;
    out.triangles.row(4 * f + 2) << ca, bc, c;
    out.triangles.row(4 * f + 3) << ab, bc, ca;
  }
  out.positions.resize(static_cast<Eigen::Index>(positions.size()), 3);
  for (std::size_t v = 0; v < positions.size(); ++v) out.positions.row(static_cast<Eigen::Index>(v)) = positions[v];
  return out;
}

// `count` points drawn uniformly by area on the mesh's faces, each with the
// unit normal interpolated from `normals` (#V) at its barycentric position:
// a point cloud with normals on exactly the mesh's surface. Seeded: the same
// cloud on every machine.
inline core::Mesh sampleSurface(const core::Mesh& mesh, const Eigen::MatrixX3d& normals, int count, unsigned seed) {
  const Eigen::VectorXd areas = core::computeDoubleAreas(mesh.positions, mesh.triangles);
  std::vector<double> cumulative(static_cast<std::size_t>(areas.size()));
  double total = 0.0;
  for (Eigen::Index f = 0; f < areas.size(); ++f) cumulative[static_cast<std::size_t>(f)] = (total += areas(f));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  core::Mesh out;
  out.positions.resize(count, 3);
  out.normals.resize(count, 3);
  for (int i = 0; i < count; ++i) {
    const double pick = unit(rng) * total;
    const auto f = static_cast<Eigen::Index>(
        std::min<std::ptrdiff_t>(std::lower_bound(cumulative.begin(), cumulative.end(), pick) - cumulative.begin(),
                                 static_cast<std::ptrdiff_t>(cumulative.size()) - 1));
    const double r1 = std::sqrt(unit(rng)), r2 = unit(rng);
    const Eigen::Vector3d w(1.0 - r1, r1 * (1.0 - r2), r1 * r2);
    Eigen::Vector3d p = Eigen::Vector3d::Zero(), n = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      p += w(k) * mesh.positions.row(mesh.triangles(f, k)).transpose();
      n += w(k) * normals.row(mesh.triangles(f, k)).transpose();
    }
    out.positions.row(i) = p.transpose();
    out.normals.row(i) = n.normalized().transpose();
  }
  return out;
}

// An even cloud on the mesh's surface: `candidates` points drawn as
// sampleSurface does, each kept unless a kept one lies within `spacing` of it
// (dart throwing: no two points closer than `spacing`, no gap much wider), as
// a scanner samples a surface more evenly than at random.
inline core::Mesh sampleSurfaceEvenly(const core::Mesh& mesh, const Eigen::MatrixX3d& normals, double spacing,
                                      int candidates, unsigned seed) {
  const core::Mesh dense = sampleSurface(mesh, normals, candidates, seed);
  std::unordered_map<long long, std::vector<int>> cells;
  const auto cellOf = [&](const Eigen::RowVector3d& p) {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / spacing)), static_cast<int>(std::floor(p.y() / spacing)),
                           static_cast<int>(std::floor(p.z() / spacing)));
  };
  const auto key = [](const Eigen::Vector3i& c) {
    return (static_cast<long long>(c.x()) * 73856093LL) ^ (static_cast<long long>(c.y()) * 19349663LL) ^
           (static_cast<long long>(c.z()) * 83492791LL);
  };
  std::vector<int> kept;
  for (Eigen::Index i = 0; i < dense.vertexCount(); ++i) {
    const Eigen::RowVector3d p = dense.positions.row(i);
    const Eigen::Vector3i c = cellOf(p);
    bool free = true;
    for (int dx = -1; dx <= 1 && free; ++dx) {
      for (int dy = -1; dy <= 1 && free; ++dy) {
        for (int dz = -1; dz <= 1 && free; ++dz) {
          const auto it = cells.find(key(c + Eigen::Vector3i(dx, dy, dz)));
          if (it == cells.end()) continue;
          for (const int j : it->second) free = free && (dense.positions.row(j) - p).norm() >= spacing;
        }
      }
    }
    if (!free) continue;
    cells[key(c)].push_back(static_cast<int>(i));
    kept.push_back(static_cast<int>(i));
  }
  core::Mesh out;
  out.positions.resize(static_cast<Eigen::Index>(kept.size()), 3);
  out.normals.resize(out.positions.rows(), 3);
  for (std::size_t k = 0; k < kept.size(); ++k) {
    out.positions.row(static_cast<Eigen::Index>(k)) = dense.positions.row(kept[k]);
    out.normals.row(static_cast<Eigen::Index>(k)) = dense.normals.row(kept[k]);
  }
  return out;
}

// A mesh's positions (and normals, turned) under a similarity.
inline core::Mesh transformed(core::Mesh mesh, const core::Similarity& s) {
  mesh.positions = ((s.scale * mesh.positions * s.rotation.transpose()).rowwise() + s.translation.transpose()).eval();
  if (mesh.normals.rows() > 0) mesh.normals = (mesh.normals * s.rotation.transpose()).eval();
  return mesh;
}

inline Eigen::MatrixX3d transformedPoints(const Eigen::MatrixX3d& points, const core::Similarity& s) {
  return (s.scale * points * s.rotation.transpose()).rowwise() + s.translation.transpose();
}

// `names` as `position` landmarks at the rows of `positions`.
inline core::LandmarkSet positionLandmarks(const core::LandmarkSet& names, const Eigen::MatrixX3d& positions) {
  core::LandmarkSet out;
  for (std::size_t i = 0; i < names.landmarks.size(); ++i) {
    core::Landmark lm;
    lm.name = names.landmarks[i].name;
    lm.kind = core::LandmarkKind::kPosition;
    lm.position = positions.row(static_cast<Eigen::Index>(i)).transpose();
    out.landmarks.push_back(std::move(lm));
  }
  return out;
}

// Position landmarks moved by a similarity.
inline core::LandmarkSet transformedLandmarks(core::LandmarkSet set, const core::Similarity& s) {
  for (core::Landmark& lm : set.landmarks) lm.position = s.apply(lm.position);
  return set;
}

}  // namespace rigport_test
