// The scan as the fit reads it (docs/FIT.md 2.1): a mesh or a point cloud with
// unit normals, flags on what must not attract the reference (borders and
// holes, spikes, detached pieces such as eyeball caps), and an index that
// answers "the nearest scan surface point to here, with its normal".
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"
#include "core/geometry/closest_point.h"
#include "core/geometry/mesh.h"
#include "core/geometry/point_cloud_index.h"

namespace core {

// Per scan point (vertex) flags.
enum ScanPointFlag : std::uint8_t {
  kScanBorder = 1,    // on (or next to) an open boundary: a crop, a hole
  kScanSpike = 2,     // off its neighbours' plane by far more than the noise
  kScanDetached = 4,  // on a small separate piece (eyeball caps, debris)
};

struct ScanReport {
  std::string file;
  int points = 0;
  int triangles = 0;
  bool point_cloud = false;
  bool normals_computed = false;   // a cloud without normals: estimated from neighbours
  int pieces = 0;                  // connected pieces of a mesh
  int detached_points = 0;
  int border_points = 0;
  int spikes = 0;
  int holes = 0;                   // open boundaries besides the longest (the crop)
  std::string units;               // mm, cm, m, in (as found or as given)
  double unit_scale = 1.0;         // scan units per reference unit
  double size_ratio = 1.0;         // the head's size against the reference's, units removed
};

// A scan correspondence: the nearest usable surface point and its normal.
struct ScanMatch {
  bool found = false;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double distance = 0.0;
  std::uint8_t flags = 0;          // of the scan point(s) it lies on (any corner's)
};

struct ScanSurface {
  Mesh mesh;                       // positions (and triangles of a mesh), in the scan's units and frame
  Eigen::MatrixX3d normals;        // #V unit normals (a cloud's may be re-oriented after alignment)
  std::vector<std::uint8_t> flags; // #V ScanPointFlag bits
  std::vector<std::vector<int>> rims;  // a mesh's closed open boundaries on the skin (crops, holes, eyes, mouth)
  double diagonal = 0.0;
  ClosestPointIndex surface_index; // a mesh: its skin faces (detached pieces skipped)
  PointCloudIndex point_index;     // its points (a mesh's vertices)
  ScanReport report;

  bool isCloud() const { return mesh.triangleCount() == 0; }
  // The nearest scan surface point of each query row (mesh: on a face, with the
  // barycentric normal; cloud: the nearest point and its normal).
  std::vector<ScanMatch> nearest(const Eigen::MatrixX3d& queries) const;
  // The scan point nearest each query in position and normal together: of
  // its nearest points, the one with the least |p - q|^2 + w^2 |n_p - n_q|^2
  // (w = normal_weight, scan units; a cloud's estimated normals unsigned).
  // A surface feature (a brow ridge, a cheekbone) draws its like, where the
  // closest point lets a smooth surface slide. Query normals unit length.
  std::vector<ScanMatch> nearestAlike(const Eigen::MatrixX3d& queries, const Eigen::MatrixX3d& query_normals,
                                      double normal_weight) const;

 private:
  // The match of scan point `index` (a cloud's point, a mesh's vertex) to `query`.
  ScanMatch matchAtPoint(int index, const Eigen::Vector3d& query) const;
};

// What a fit needs of a scan, checked alone (a service answers at
// submission): finite values, at least 100 points, not all at one position.
Status checkScan(const Mesh& scan, const std::string& label);

// checkScan, then the scan prepared.
Result<ScanSurface> prepareScan(Mesh scan, const std::string& label);

}  // namespace core
