// Geodesic distance on a triangle mesh by the heat method (Crane, Weischedel
// and Wardetzky 2013): heat flow from a source for a short time t, normalised
// gradient, Poisson solve. Both sparse systems depend only on the mesh, so
// they are factorised once (GeodesicSolver) and reused for every source: the
// papers' (002) precomputed "distance matrix", at a fraction of its cost.
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/closest_point.h"  // SurfacePoint: a source is a face + barycentric (point, distance unused)
#include "core/base/error.h"
#include "core/geometry/mesh.h"

namespace core {

struct GeodesicOptions {
  // Heat time t = time_factor * h^2, h = mean edge length (Crane et al. use 1).
  double time_factor = 4.0;
  // On meshes with boundaries, average the Neumann and zero-Dirichlet heat solutions (Crane et al. sec. 3.2.2).
  bool average_boundary_conditions = true;
  // Heat step only: clamp negative cotangent weights (non-Delaunay edges) to 0, making M + tL an M-matrix.
  bool clamp_heat_weights = false;
};

class GeodesicSolver {
 public:
  // Factorises the heat and Poisson systems of `mesh` (cotangent Laplacian,
  // lumped mass). Errors name `label` when the mesh has no usable triangles
  // or a system cannot be factorised.
  static Result<GeodesicSolver> create(const Mesh& mesh, const std::string& label, const GeodesicOptions& options = {});

  // Distance from each source point to every vertex: #sources by #V, model
  // units, >= 0; vertices in a component not containing a source get +Inf.
  // Sources are independent: runs on the ScopedThreadCount's threads with
  // results that do not depend on the thread count (bitwise).
  // Accuracy (tests/core/solve/geodesic_test.cpp, default options): relative error
  // beyond 5 mean edge lengths from the source, mean < 0.5%, max < 2% on a
  // 10k-vertex sphere and a jittered plane; sources inside a triangle reach
  // ~2.4% at 5-8 edges. A source ON an open boundary keeps only the Neumann
  // heat solution and is anisotropic (up to ~10%: short along the boundary).
  // The value at the source is 0; the far field's additive constant is fitted
  // on the source's two vertex rings (see geodesic.cpp).
  // A source face out of range is a programmer error (asserted; its row is NaN
  // in release builds).
  Eigen::MatrixXd distances(const std::vector<SurfacePoint>& sources) const;

  Eigen::Index vertexCount() const;

  GeodesicSolver(GeodesicSolver&&) noexcept;
  GeodesicSolver& operator=(GeodesicSolver&&) noexcept;
  ~GeodesicSolver();

  struct Data;  // the factorised systems and per-vertex tables (geodesic.cpp, read by its stages)

 private:
  explicit GeodesicSolver(std::unique_ptr<Data> data);
  std::unique_ptr<Data> data_;
};

}  // namespace core
