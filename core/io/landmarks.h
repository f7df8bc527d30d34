// Landmarks: named points on a mesh, in the JSON format of DESIGN.md:
//   {"landmarks":[{"name":"nose_tip","vertex":1234}, ...]}
// with exactly one of `vertex`, `position` [x,y,z], or `face` + `barycentric`.
// Source and target landmarks correspond by name.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"
#include "core/geometry/mesh.h"

namespace core {

class ClosestPointIndex;
struct TpsOptions;

enum class LandmarkKind { kVertex, kPosition, kFace };

struct Landmark {
  std::string name;
  LandmarkKind kind = LandmarkKind::kVertex;
  int vertex = -1;                                         // kVertex: vertex index
  Eigen::Vector3d position = Eigen::Vector3d::Zero();      // kPosition: model units
  int face = -1;                                           // kFace: triangle index (index buffer / 3)
  Eigen::Vector3d barycentric = Eigen::Vector3d::Zero();   // kFace: weights of the triangle's corners, sum 1
};

struct LandmarkSet {
  std::vector<Landmark> landmarks;  // names unique
  int indexOf(std::string_view name) const;  // -1 when absent
};

// Parses landmarks JSON; `label` (usually the file name) starts every message.
Result<LandmarkSet> parseLandmarks(std::string_view json_text, const std::string& label);
Result<LandmarkSet> readLandmarks(const std::filesystem::path& path);

// Serialises a landmark set in the same format (deterministic).
std::string formatLandmarks(const LandmarkSet& set);

struct ResolveLandmarksOptions {
  // `position` landmarks farther than this fraction of the bbox diagonal from the surface are "off the mesh".
  double max_off_surface = 0.01;
};

// Positions of the landmarks on `mesh` (#L by 3, model units), checking index
// ranges and barycentrics. `index` (of the same mesh) speeds up the off-surface
// check of `position` landmarks; without it the check is brute force.
Result<Eigen::MatrixX3d> resolveLandmarks(const LandmarkSet& set, const Mesh& mesh, const std::string& label,
                                          const ClosestPointIndex* index = nullptr,
                                          const ResolveLandmarksOptions& options = {});

// The mesh vertex standing for each landmark of a resolved set (`positions`
// from resolveLandmarks): its own vertex, its face's corner of largest
// barycentric, or for a `position` the corner of largest barycentric of its
// closest face on `index` (without an index: the nearest vertex, brute force).
// -1 when a `position` finds no face.
std::vector<int> landmarkVertices(const LandmarkSet& set, const Mesh& mesh, const Eigen::MatrixX3d& positions,
                                  const ClosestPointIndex* index = nullptr);

// Source and target landmarks paired by name.
struct LandmarkPairs {
  std::vector<std::string> names;  // in source order
  Eigen::MatrixX3d source;         // #P by 3 source positions
  Eigen::MatrixX3d target;         // #P by 3 target positions
};

// Every target name must exist in the source (an unknown name is an error, not
// a silent skip); the target may use any subset of >= 4 names. Names only, so
// it can be checked before any mesh is read.
Status checkSharedLandmarkNames(const LandmarkSet& source, const LandmarkSet& target, const std::string& target_label);

// checkSharedLandmarkNames, then the positions paired in source order.
Result<LandmarkPairs> pairLandmarks(const LandmarkSet& source, const Eigen::MatrixX3d& source_positions,
                                    const LandmarkSet& target, const Eigen::MatrixX3d& target_positions,
                                    const std::string& target_label);

// What a landmark warp needs of a target, checked alone so that a service can
// answer at submission what the warp would refuse later: a surface mesh
// (validateSurfaceMesh), landmark names shared with the source
// (checkSharedLandmarkNames) and, at `target_positions` (resolveLandmarks),
// shared landmarks that span 3D (checkTpsCentres with `landmark_tps`).
Status checkWarpTarget(const LandmarkSet& source, const Mesh& target, const LandmarkSet& target_landmarks,
                       const Eigen::MatrixX3d& target_positions, const std::string& target_label,
                       const TpsOptions& landmark_tps);

}  // namespace core
