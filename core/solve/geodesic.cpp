// Geodesic distance by the heat method: K. Crane, C. Weischedel, M. Wardetzky,
// "Geodesics in Heat: A New Approach to Computing Distance Based on Heat Flow",
// ACM TOG 32(5), 2013. Discretisation (sec. 3.2): P1 finite elements, i.e. the
// cotangent Laplacian L and the barycentric lumped mass M;
//   1. heat:    (M + t L) u = delta_source                  (one backward Euler step)
//   2. field:   X = -grad u / |grad u|                       (per face)
//   3. Poisson: L phi = div X                                (integrated divergence)
//   4. shift:   phi's additive constant (see distances(): fitted near the source)
// Boundary conditions (sec. 3.2.2): u is the average of the Neumann and the
// Dirichlet (u = 0 on the boundary) heat solutions, which keeps the distance
// isolines from bending towards open boundaries (mouth, eyes, neck cut):
// measured on a plane, mean relative error 2.5% -> 0.3% for a source near a
// corner. Degenerate (zero-area) triangles are skipped; vertices on no usable
// triangle are eliminated (identity rows) and get +Inf.
//
// Layout for speed: vertices are renumbered once by an AMD fill-reducing
// ordering so the three factorisations need no permutation at solve time, and
// sources are solved in blocks of up to kMaxBlock right-hand sides stored
// row-major, so each factor entry is loaded once per block (the triangular
// solves are memory-bound). Every column of a block goes through the same
// scalar operations whatever the block's width (ISO C++ mode: no FMA
// contraction; no reassociation), so results do not depend on how sources are
// split into blocks, hence not on the thread count (tested bitwise).
#include "core/solve/geodesic.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <span>
#include <unordered_map>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "core/base/parallel.h"

namespace core {

namespace {

using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
// The matrices are assembled in AMD order already, so the factorisation uses
// the natural ordering.
using Factor = Eigen::SimplicialLDLT<SpMat, Eigen::Lower, Eigen::NaturalOrdering<int>>;

constexpr int kMaxBlock = 16;  // right-hand sides per solve block at most (measured: 16 beats 8)
constexpr double kInf = std::numeric_limits<double>::infinity();

// Row-major #V by W block of right-hand sides / solutions.
using Block = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Solves L D L^T x = b in place for the W columns of `x` (row-major, width w).
// Eigen's own solve handles one column at a time and so streams the factor W
// times; here the inner loop runs over the block's columns.
template <int W>
void solveLdlt(const Factor& factor, Block& x) {
  const SpMat& l = factor.matrixL().nestedExpression();  // strictly lower part, column-major
  const auto& d = factor.vectorD();
  const int n = static_cast<int>(l.cols());
  const int* outer = l.outerIndexPtr();
  const int* inner = l.innerIndexPtr();
  const double* value = l.valuePtr();
  double* data = x.data();
  for (int j = 0; j < n; ++j) {  // forward: L y = b
    const double* xj = data + static_cast<std::ptrdiff_t>(j) * W;
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      double* xi = data + static_cast<std::ptrdiff_t>(inner[p]) * W;
      const double lij = value[p];
      for (int c = 0; c < W; ++c) xi[c] -= lij * xj[c];
    }
  }
  for (int j = 0; j < n; ++j) {  // diagonal
    double* xj = data + static_cast<std::ptrdiff_t>(j) * W;
    const double inv = 1.0 / d(j);
    for (int c = 0; c < W; ++c) xj[c] *= inv;
  }
  for (int j = n - 1; j >= 0; --j) {  // backward: L^T x = z
    double* xj = data + static_cast<std::ptrdiff_t>(j) * W;
    double acc[W];
    for (int c = 0; c < W; ++c) acc[c] = xj[c];
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      const double* xi = data + static_cast<std::ptrdiff_t>(inner[p]) * W;
      const double lij = value[p];
      for (int c = 0; c < W; ++c) acc[c] -= lij * xi[c];
    }
    for (int c = 0; c < W; ++c) xj[c] = acc[c];
  }
}

// Dispatches to the kernel compiled for the block's width (1..kMaxBlock).
template <int W>
void solveBlockUpTo(const Factor& factor, Block& x) {
  if constexpr (W > 1) {
    if (x.cols() < W) return solveBlockUpTo<W - 1>(factor, x);
  }
  solveLdlt<W>(factor, x);
}

void solveBlock(const Factor& factor, Block& x) {
  assert(x.cols() >= 1 && x.cols() <= kMaxBlock);
  solveBlockUpTo<kMaxBlock>(factor, x);
}

// Union-find over triangles: connected components of the usable surface.
int findRoot(std::vector<int>& parent, int v) {
  while (parent[static_cast<std::size_t>(v)] != v) {
    parent[static_cast<std::size_t>(v)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(v)])];
    v = parent[static_cast<std::size_t>(v)];
  }
  return v;
}

std::uint64_t edgeKey(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) | static_cast<std::uint32_t>(b);
}

// Factorises `matrix` (lower triangle used); false when not positive definite.
bool factorise(Factor& factor, const SpMat& matrix) {
  factor.compute(matrix);
  return factor.info() == Eigen::Success && (factor.vectorD().array() > 0.0).all();
}

}  // namespace

struct GeodesicSolver::Data {
  Eigen::Index vertex_count = 0;
  Eigen::MatrixX3i triangles;            // the mesh's triangles (original vertex indices), for sources
  std::vector<int> order;                // original vertex -> solver (AMD) index
  std::vector<int> component;            // per solver index: component id, -1 for vertices on no usable triangle
  // Usable triangles in solver indices, with per-face area-weighted hat
  // gradients: grad_area[f][c] = area_f * grad(phi_c) (the divergence weights)
  // and grad[f][c] = grad(phi_c).
  std::vector<std::array<int, 3>> faces;
  std::vector<std::array<Eigen::Vector3d, 3>> grad;
  std::vector<double> area;
  Factor heat_neumann;
  Factor heat_dirichlet;
  bool has_dirichlet = false;            // false when the mesh is closed (Dirichlet = Neumann)
  std::vector<char> boundary;            // per solver index: on an edge of one usable triangle
  Factor poisson;                        // L with one pinned vertex per component
  std::vector<char> pinned;              // per solver index
  RowMatrixX3d positions;                // #V by 3, solver order (for the offset calibration)
  std::vector<int> neighbour_offsets;    // CSR vertex adjacency in solver order (#V + 1)
  std::vector<int> neighbours;
  double mean_edge = 0.0;                // h, model units
};

namespace {

// create(): the mesh's operators, numbered for the solver.

// A usable (non-degenerate) triangle: cotangents, area, hat gradients, in
// original vertex indices.
struct FaceGeometry {
  std::array<int, 3> v;
  std::array<double, 3> cot;  // cotangent of the angle at corner c
  std::array<Eigen::Vector3d, 3> grad;
  double area;
};

struct SurfaceGeometry {
  std::vector<FaceGeometry> faces;  // the usable triangles, in the mesh's order
  double mean_edge = 0.0;           // h over the usable triangles, model units
};

Status checkGeodesicInput(const Mesh& mesh, const std::string& label, const GeodesicOptions& options) {
  if (Status valid = validateMesh(mesh, label); !valid) return valid.error();
  if (!(options.time_factor > 0.0) || !std::isfinite(options.time_factor)) {
    return makeError(ErrorCode::kInvalidArgument,
                     label + ": geodesic time_factor must be a positive finite number (got " +
                         std::to_string(options.time_factor) + ")");
  }
  if (mesh.triangleCount() == 0) {
    return makeError(ErrorCode::kInvalidMesh, label + ": geodesic distances need triangles (the mesh has none)");
  }
  return Ok{};
}

SurfaceGeometry measureFaces(const Mesh& mesh) {
  const double diagonal = boundingBoxDiagonal(mesh.positions);
  SurfaceGeometry out;
  std::vector<FaceGeometry>& geometry = out.faces;
  geometry.reserve(static_cast<std::size_t>(mesh.triangleCount()));
  double edge_sum = 0.0;
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    const Eigen::Vector3i t = mesh.triangles.row(f).transpose();
    if (isDegenerateTriangle(mesh.positions, t, diagonal)) continue;
    FaceGeometry g;
    std::array<Eigen::Vector3d, 3> p;
    for (int c = 0; c < 3; ++c) {
      g.v[static_cast<std::size_t>(c)] = t(c);
      p[static_cast<std::size_t>(c)] = mesh.positions.row(t(c)).transpose();
    }
    const Eigen::Vector3d n = (p[1] - p[0]).cross(p[2] - p[0]);
    const double double_area = n.norm();
    if (!(double_area > 0.0) || !std::isfinite(double_area)) continue;
    g.area = 0.5 * double_area;
    const Eigen::Vector3d unit_normal = n / double_area;
    bool finite = true;
    double edges = 0.0;
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3d& pi = p[static_cast<std::size_t>(c)];
      const Eigen::Vector3d& pj = p[static_cast<std::size_t>((c + 1) % 3)];
      const Eigen::Vector3d& pk = p[static_cast<std::size_t>((c + 2) % 3)];
      g.cot[static_cast<std::size_t>(c)] = (pj - pi).dot(pk - pi) / double_area;
      // grad phi_i = N x (p_k - p_j) / (2 area): perpendicular to the opposite edge, towards i.
      g.grad[static_cast<std::size_t>(c)] = unit_normal.cross(pk - pj) / double_area;
      edges += (pk - pj).norm();
      finite = finite && std::isfinite(g.cot[static_cast<std::size_t>(c)]) &&
               g.grad[static_cast<std::size_t>(c)].allFinite();
    }
    if (!finite) continue;
    geometry.push_back(g);
    edge_sum += edges;
  }
  if (!geometry.empty()) out.mean_edge = edge_sum / (3.0 * static_cast<double>(geometry.size()));
  return out;
}

// Components, boundary vertices (edges of one usable triangle), original
// vertex indices.
struct SurfaceTopology {
  std::vector<int> root;         // #V: the lowest vertex of the vertex's component
  std::vector<char> on_triangle; // #V: on a usable triangle
  std::vector<char> boundary;    // #V
};

SurfaceTopology surfaceTopology(const std::vector<FaceGeometry>& geometry, Eigen::Index nv) {
  SurfaceTopology out;
  std::vector<int> parent(static_cast<std::size_t>(nv));
  std::iota(parent.begin(), parent.end(), 0);
  out.on_triangle.assign(static_cast<std::size_t>(nv), 0);
  std::unordered_map<std::uint64_t, int> edge_use;
  edge_use.reserve(geometry.size() * 2);
  for (const FaceGeometry& g : geometry) {
    for (int c = 0; c < 3; ++c) {
      const int a = g.v[static_cast<std::size_t>(c)], b = g.v[static_cast<std::size_t>((c + 1) % 3)];
      out.on_triangle[static_cast<std::size_t>(a)] = 1;
      ++edge_use[edgeKey(a, b)];
      const int ra = findRoot(parent, a), rb = findRoot(parent, b);
      if (ra != rb) parent[static_cast<std::size_t>(std::max(ra, rb))] = std::min(ra, rb);
    }
  }
  out.boundary.assign(static_cast<std::size_t>(nv), 0);
  for (const auto& [key, count] : edge_use) {
    if (count == 1) {
      out.boundary[static_cast<std::size_t>(key >> 32)] = 1;
      out.boundary[static_cast<std::size_t>(key & 0xffffffffu)] = 1;
    }
  }
  out.root.resize(static_cast<std::size_t>(nv));
  for (int v = 0; v < static_cast<int>(nv); ++v) out.root[static_cast<std::size_t>(v)] = findRoot(parent, v);
  return out;
}

// Cotangent Laplacian (positive semi-definite: L = G^T A G; every diagonal
// entry stored) and lumped mass, original vertex indices.
struct CotanOperators {
  SpMat laplacian;       // #V by #V
  Eigen::VectorXd mass;  // #V
};

CotanOperators cotanOperators(const std::vector<FaceGeometry>& geometry, Eigen::Index nv) {
  std::vector<Eigen::Triplet<double, int>> laplacian_entries;
  laplacian_entries.reserve(geometry.size() * 12);
  CotanOperators out;
  out.mass = Eigen::VectorXd::Zero(nv);
  for (const FaceGeometry& g : geometry) {
    for (int c = 0; c < 3; ++c) {
      const int j = g.v[static_cast<std::size_t>((c + 1) % 3)], k = g.v[static_cast<std::size_t>((c + 2) % 3)];
      const double w = 0.5 * g.cot[static_cast<std::size_t>(c)];
      laplacian_entries.emplace_back(j, k, -w);
      laplacian_entries.emplace_back(k, j, -w);
      laplacian_entries.emplace_back(j, j, w);
      laplacian_entries.emplace_back(k, k, w);
      out.mass(g.v[static_cast<std::size_t>(c)]) += g.area / 3.0;
    }
  }
  for (Eigen::Index v = 0; v < nv; ++v) laplacian_entries.emplace_back(static_cast<int>(v), static_cast<int>(v), 0.0);
  out.laplacian.resize(nv, nv);
  out.laplacian.setFromTriplets(laplacian_entries.begin(), laplacian_entries.end());
  return out;
}

// Fill-reducing order, applied once to the vertex numbering.
struct SolverOrder {
  std::vector<int> order;  // original vertex -> solver index
  SpMat permuted;          // the Laplacian's lower triangle (diagonal included) in solver order
};

SolverOrder fillReducingOrder(const SpMat& laplacian) {
  const Eigen::Index nv = laplacian.rows();
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> inverse_order;
  Eigen::AMDOrdering<int>()(laplacian, inverse_order);
  const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> order = inverse_order.inverse();
  SolverOrder out;
  out.order.assign(order.indices().data(), order.indices().data() + nv);
  out.permuted.resize(nv, nv);
  out.permuted.selfadjointView<Eigen::Lower>() = laplacian.selfadjointView<Eigen::Lower>().twistedBy(order);
  return out;
}

// Per-vertex data by solver index; components numbered in the order of
// their lowest original vertex, which is pinned (fixes phi's constant).
struct SolverVertices {
  Eigen::VectorXd mass;
  std::vector<char> boundary, on_triangle, pinned;
  std::vector<int> component;  // -1 for vertices on no usable triangle
};

SolverVertices toSolverOrder(const std::vector<int>& ord, const SurfaceTopology& topology, const Eigen::VectorXd& mass) {
  const auto nv = static_cast<Eigen::Index>(ord.size());
  SolverVertices out;
  out.mass.resize(nv);
  out.boundary.resize(static_cast<std::size_t>(nv));
  out.on_triangle.resize(static_cast<std::size_t>(nv));
  out.component.assign(static_cast<std::size_t>(nv), -1);
  out.pinned.assign(static_cast<std::size_t>(nv), 0);
  std::vector<int> component_id(static_cast<std::size_t>(nv), -1);  // by original root
  int components = 0;
  for (Eigen::Index v = 0; v < nv; ++v) {
    const auto vi = static_cast<std::size_t>(v);
    const auto pv = static_cast<std::size_t>(ord[vi]);
    out.mass(static_cast<Eigen::Index>(pv)) = mass(v);
    out.boundary[pv] = topology.boundary[vi];
    out.on_triangle[pv] = topology.on_triangle[vi];
    if (!topology.on_triangle[vi]) continue;
    const auto root = static_cast<std::size_t>(topology.root[vi]);
    if (component_id[root] < 0) {
      component_id[root] = components++;
      out.pinned[pv] = 1;  // first (lowest original index) vertex of each component fixes phi's constant
    }
    out.component[pv] = component_id[root];
  }
  return out;
}

// The Laplacian's diagonal with negative edge weights (edges that are not
// locally Delaunay) clamped to zero (GeodesicOptions::clamp_heat_weights).
Eigen::VectorXd clampedDiagonal(const SpMat& permuted) {
  Eigen::VectorXd clamped_diagonal = Eigen::VectorXd::Zero(permuted.rows());
  for (int col = 0; col < permuted.outerSize(); ++col) {
    for (SpMat::InnerIterator it(permuted, col); it; ++it) {
      if (it.row() == col) continue;
      const double w = std::max(0.0, -it.value());
      clamped_diagonal(it.row()) += w;
      clamped_diagonal(col) += w;
    }
  }
  return clamped_diagonal;
}

// One system on the Laplacian's pattern: mass_weight M + laplacian_weight L
// (L clamped when `clamped_diagonal` is given), with the identity in the
// rows/columns of `eliminate`d vertices and of vertices on no usable triangle.
SpMat assembleSystem(const SpMat& permuted, const SolverVertices& vertices, double mass_weight,
                     double laplacian_weight, const std::vector<char>& eliminate,
                     const Eigen::VectorXd* clamped_diagonal) {
  SpMat a = permuted;
  for (int col = 0; col < a.outerSize(); ++col) {
    for (SpMat::InnerIterator it(a, col); it; ++it) {
      const auto r = static_cast<std::size_t>(it.row()), c = static_cast<std::size_t>(col);
      const bool drop = eliminate[r] || eliminate[c] || !vertices.on_triangle[r] || !vertices.on_triangle[c];
      if (it.row() == col) {
        const double l = clamped_diagonal != nullptr ? (*clamped_diagonal)(col) : it.value();
        it.valueRef() = drop ? 1.0 : mass_weight * vertices.mass(col) + laplacian_weight * l;
      } else {
        const double l = clamped_diagonal != nullptr ? std::min(0.0, it.value()) : it.value();
        it.valueRef() = drop ? 0.0 : laplacian_weight * l;
      }
    }
  }
  return a;
}

// Three systems on one pattern, factorised into `data`: the heat system
// (M + tL) with Neumann and, when averaging on a mesh with boundary,
// zero-Dirichlet conditions; the Poisson system L with one pinned vertex per
// component. A row/column is replaced by the identity for vertices that are
// eliminated: Dirichlet boundary (heat), pinned (Poisson), and vertices on no
// usable triangle (all three).
// Optionally (GeodesicOptions::clamp_heat_weights) the heat systems use the
// Laplacian with negative edge weights (edges that are not locally
// Delaunay) clamped to zero: M + tL is then an M-matrix, so u stays
// positive and decays monotonically instead of turning into cancellation
// noise far from the source on meshes with many obtuse triangles. A cheap
// stand-in for the intrinsic Delaunay Laplacian (Sharp and Crane 2020); the
// Poisson step always keeps the exact cotangent operator.
Status factoriseSystems(GeodesicSolver::Data& data, const SpMat& permuted, const SolverVertices& vertices, double t,
                        const GeodesicOptions& options, const std::string& label) {
  const Eigen::VectorXd clamped_diagonal = clampedDiagonal(permuted);
  const Eigen::VectorXd* heat_clamp = options.clamp_heat_weights ? &clamped_diagonal : nullptr;
  const std::vector<char> none(vertices.on_triangle.size(), 0);
  if (!factorise(data.heat_neumann, assembleSystem(permuted, vertices, 1.0, t, none, heat_clamp))) {
    return makeError(ErrorCode::kInvalidMesh, label + ": geodesic heat system could not be factorised");
  }
  data.has_dirichlet = options.average_boundary_conditions &&
                       std::any_of(vertices.boundary.begin(), vertices.boundary.end(), [](char b) { return b != 0; });
  if (data.has_dirichlet &&
      !factorise(data.heat_dirichlet, assembleSystem(permuted, vertices, 1.0, t, vertices.boundary, heat_clamp))) {
    return makeError(ErrorCode::kInvalidMesh, label + ": geodesic heat system (Dirichlet) could not be factorised");
  }
  if (!factorise(data.poisson, assembleSystem(permuted, vertices, 0.0, 1.0, vertices.pinned, nullptr))) {
    return makeError(ErrorCode::kInvalidMesh, label + ": geodesic Poisson system could not be factorised");
  }
  return Ok{};
}

// CSR vertex adjacency in solver order, from the (symmetric) pattern of the
// permuted Laplacian's lower triangle.
struct Adjacency {
  std::vector<int> offsets;  // #V + 1
  std::vector<int> neighbours;
};

Adjacency solverAdjacency(const SpMat& permuted) {
  std::vector<std::vector<int>> adjacency(static_cast<std::size_t>(permuted.rows()));
  for (int col = 0; col < permuted.outerSize(); ++col) {
    for (SpMat::InnerIterator it(permuted, col); it; ++it) {
      if (it.row() == col) continue;  // every off-diagonal entry is a mesh edge
      adjacency[static_cast<std::size_t>(col)].push_back(static_cast<int>(it.row()));
      adjacency[static_cast<std::size_t>(it.row())].push_back(col);
    }
  }
  Adjacency out;
  out.offsets.assign(1, 0);
  for (const auto& a : adjacency) {
    out.neighbours.insert(out.neighbours.end(), a.begin(), a.end());
    out.offsets.push_back(static_cast<int>(out.neighbours.size()));
  }
  return out;
}

}  // namespace

GeodesicSolver::GeodesicSolver(std::unique_ptr<Data> data) : data_(std::move(data)) {}
GeodesicSolver::GeodesicSolver(GeodesicSolver&&) noexcept = default;
GeodesicSolver& GeodesicSolver::operator=(GeodesicSolver&&) noexcept = default;
GeodesicSolver::~GeodesicSolver() = default;

Eigen::Index GeodesicSolver::vertexCount() const { return data_->vertex_count; }

Result<GeodesicSolver> GeodesicSolver::create(const Mesh& mesh, const std::string& label,
                                              const GeodesicOptions& options) {
  if (Status valid = checkGeodesicInput(mesh, label, options); !valid) return valid.error();
  const Eigen::Index nv = mesh.vertexCount();
  const SurfaceGeometry geometry = measureFaces(mesh);
  if (geometry.faces.empty()) {
    return makeError(ErrorCode::kInvalidMesh,
                     label + ": geodesic distances need non-degenerate triangles (all " +
                         std::to_string(mesh.triangleCount()) + " have zero area)");
  }
  const double h = geometry.mean_edge;
  const double t = options.time_factor * h * h;
  const SurfaceTopology topology = surfaceTopology(geometry.faces, nv);
  const CotanOperators operators = cotanOperators(geometry.faces, nv);
  const SolverOrder solver = fillReducingOrder(operators.laplacian);
  SolverVertices vertices = toSolverOrder(solver.order, topology, operators.mass);

  auto data = std::make_unique<Data>();
  data->vertex_count = nv;
  data->triangles = mesh.triangles;
  data->order = solver.order;
  if (Status ok = factoriseSystems(*data, solver.permuted, vertices, t, options, label); !ok) return ok.error();
  data->boundary = std::move(vertices.boundary);
  data->component = std::move(vertices.component);
  data->pinned = std::move(vertices.pinned);
  data->mean_edge = h;
  const auto& ord = data->order;
  data->positions.resize(nv, 3);
  for (Eigen::Index v = 0; v < nv; ++v) data->positions.row(ord[static_cast<std::size_t>(v)]) = mesh.positions.row(v);
  Adjacency adjacency = solverAdjacency(solver.permuted);
  data->neighbour_offsets = std::move(adjacency.offsets);
  data->neighbours = std::move(adjacency.neighbours);
  data->faces.reserve(geometry.faces.size());
  data->grad.reserve(geometry.faces.size());
  data->area.reserve(geometry.faces.size());
  for (const FaceGeometry& g : geometry.faces) {
    data->faces.push_back({ord[static_cast<std::size_t>(g.v[0])], ord[static_cast<std::size_t>(g.v[1])],
                           ord[static_cast<std::size_t>(g.v[2])]});
    data->grad.push_back(g.grad);
    data->area.push_back(g.area);
  }
  return GeodesicSolver(std::move(data));
}

namespace {

// distances(): a block of sources through the four steps.

// Fewest blocks of at most kMaxBlock sources, but at least one per thread
// (down to 4 sources a block), with balanced widths.
struct SourceBlocks {
  std::ptrdiff_t count = 0;
  std::ptrdiff_t base_width = 0, wider = 0;  // the first `wider` blocks take one source more
  Eigen::Index start(std::ptrdiff_t b) const { return b * base_width + std::min(b, wider); }
};

SourceBlocks sourceBlocks(Eigen::Index ns) {
  const std::ptrdiff_t thread_count = ScopedThreadCount::resolved();
  SourceBlocks out;
  out.count = (ns + kMaxBlock - 1) / kMaxBlock;
  out.count = std::max(out.count, std::min<std::ptrdiff_t>(thread_count, (ns + 3) / 4));
  out.base_width = out.count > 0 ? ns / out.count : 0;
  out.wider = out.count > 0 ? ns % out.count : 0;
  return out;
}

// A block's sources on the solver's vertices: the heat put at each source
// (its barycentrics on its face's corners), the corners (solver indices),
// and the component of its heaviest usable corner (-1: none).
struct PlacedSources {
  Block heat;                                // #V by w
  std::vector<std::array<int, 3>> corners;   // w
  std::vector<Eigen::Vector3d> weights;      // w: barycentrics
  std::vector<int> main_component;           // w
};

PlacedSources placeSources(const GeodesicSolver::Data& d, std::span<const SurfacePoint> sources) {
  const auto w = static_cast<Eigen::Index>(sources.size());
  PlacedSources out;
  out.main_component.assign(static_cast<std::size_t>(w), -1);
  out.corners.resize(static_cast<std::size_t>(w));
  out.weights.resize(static_cast<std::size_t>(w));
  out.heat = Block::Zero(d.vertex_count, w);
  for (Eigen::Index c = 0; c < w; ++c) {
    const SurfacePoint& sp = sources[static_cast<std::size_t>(c)];
    assert(sp.face >= 0 && sp.face < d.triangles.rows() && "source face out of range");
    if (sp.face < 0 || sp.face >= d.triangles.rows()) continue;
    const auto ci = static_cast<std::size_t>(c);
    double best = -1.0;
    for (int k = 0; k < 3; ++k) {
      const int v = d.order[static_cast<std::size_t>(d.triangles(sp.face, k))];
      out.corners[ci][static_cast<std::size_t>(k)] = v;
      out.heat(v, c) += sp.barycentric(k);
      const int comp = d.component[static_cast<std::size_t>(v)];
      if (comp >= 0 && sp.barycentric(k) > best) {
        best = sp.barycentric(k);
        out.main_component[ci] = comp;
      }
    }
    out.weights[ci] = sp.barycentric;
  }
  return out;
}

// 1. Heat flow, averaging Neumann and Dirichlet solutions.
Block flowHeat(const GeodesicSolver::Data& d, const Block& heat) {
  Block u = heat;
  solveBlock(d.heat_neumann, u);
  if (d.has_dirichlet) {
    Block u_dirichlet = heat;
    for (Eigen::Index v = 0; v < d.vertex_count; ++v) {
      if (d.boundary[static_cast<std::size_t>(v)]) u_dirichlet.row(v).setZero();  // u = 0 on the boundary
    }
    solveBlock(d.heat_dirichlet, u_dirichlet);
    u += u_dirichlet;  // the average, up to a factor the normalisation removes
  }
  return u;
}

// 2-3. Normalised negative gradient per face, integrated divergence.
// Plain arrays over the block's columns so the compiler vectorises them.
Block integratedDivergence(const GeodesicSolver::Data& d, const Block& u) {
  const Eigen::Index w = u.cols();
  Block divergence = Block::Zero(d.vertex_count, w);
  std::array<double, kMaxBlock> gx, gy, gz;
  for (std::size_t f = 0; f < d.faces.size(); ++f) {
    const auto& face = d.faces[f];
    const auto& grad = d.grad[f];
    const double* u0 = u.data() + static_cast<std::ptrdiff_t>(face[0]) * w;
    const double* u1 = u.data() + static_cast<std::ptrdiff_t>(face[1]) * w;
    const double* u2 = u.data() + static_cast<std::ptrdiff_t>(face[2]) * w;
    for (Eigen::Index c = 0; c < w; ++c) {
      gx[c] = u0[c] * grad[0].x() + u1[c] * grad[1].x() + u2[c] * grad[2].x();
      gy[c] = u0[c] * grad[0].y() + u1[c] * grad[1].y() + u2[c] * grad[2].y();
      gz[c] = u0[c] * grad[0].z() + u1[c] * grad[1].z() + u2[c] * grad[2].z();
      const double norm = std::sqrt(gx[c] * gx[c] + gy[c] * gy[c] + gz[c] * gz[c]);
      // X = -grad u / |grad u|, weighted by the face area; 0 where u is flat.
      const double scale = norm > 0.0 && std::isfinite(norm) ? -d.area[f] / norm : 0.0;
      gx[c] *= scale;
      gy[c] *= scale;
      gz[c] *= scale;
    }
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d& gk = grad[static_cast<std::size_t>(k)];
      double* div = divergence.data() + static_cast<std::ptrdiff_t>(face[static_cast<std::size_t>(k)]) * w;
      for (Eigen::Index c = 0; c < w; ++c) div[c] += gk.x() * gx[c] + gk.y() * gy[c] + gk.z() * gz[c];
    }
  }
  return divergence;
}

// 4. Poisson solve L phi = div X with one pinned vertex per component.
Block solvePoisson(const GeodesicSolver::Data& d, Block divergence) {
  for (Eigen::Index v = 0; v < d.vertex_count; ++v) {
    if (d.pinned[static_cast<std::size_t>(v)] || d.component[static_cast<std::size_t>(v)] < 0) {
      divergence.row(v).setZero();
    }
  }
  solveBlock(d.poisson, divergence);
  return divergence;
}

// Vertices one and two edges away from the source face's corners (corners
// excluded), in component `comp`; sorted, unique.
std::vector<int> ringsAround(const GeodesicSolver::Data& d, const std::array<int, 3>& corners, int comp) {
  std::vector<int> ring;
  auto expand = [&](int v) {
    for (int p = d.neighbour_offsets[static_cast<std::size_t>(v)];
         p < d.neighbour_offsets[static_cast<std::size_t>(v) + 1]; ++p) {
      ring.push_back(d.neighbours[static_cast<std::size_t>(p)]);
    }
  };
  for (int v : corners) expand(v);
  std::sort(ring.begin(), ring.end());
  ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
  const std::vector<int> first = ring;
  for (int v : first) expand(v);
  std::sort(ring.begin(), ring.end());
  ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
  std::erase_if(ring, [&](int v) {
    return d.component[static_cast<std::size_t>(v)] != comp ||
           std::find(corners.begin(), corners.end(), v) != corners.end();
  });
  return ring;
}

// 5. What to subtract from phi per source: the value at the source and the
// far field's constant, blended over ~h around the source point.
struct SourceShifts {
  Eigen::MatrixX3d points;      // w by 3: the sources, solver positions
  Eigen::VectorXd values;       // w: phi at the source
  Eigen::VectorXd far_values;   // w: phi - distance on the rings around it
  std::vector<int> components;  // w: the source's component; -1: none (+Inf row), -2: face out of range (NaN row)
};

SourceShifts sourceShifts(const GeodesicSolver::Data& d, std::span<const SurfacePoint> sources,
                          const PlacedSources& placed, const Block& phi) {
  const Eigen::Index w = phi.cols();
  SourceShifts out;
  out.points.resize(w, 3);
  out.values.resize(w);
  out.far_values.resize(w);
  out.components.assign(static_cast<std::size_t>(w), -1);
  for (Eigen::Index c = 0; c < w; ++c) {
    const auto ci = static_cast<std::size_t>(c);
    const int comp = placed.main_component[ci];
    if (comp < 0) {
      const int face = sources[static_cast<std::size_t>(c)].face;
      // -2: a face out of range (NaN row); -1: no usable corner (+Inf row).
      out.components[ci] = face < 0 || face >= d.triangles.rows() ? -2 : -1;
      continue;
    }
    // phi is known up to a constant. At the source it is phi interpolated
    // there; but the heat flow rounds the distance cone's tip over about
    // sqrt(t), which raises the source value by ~0.1-0.15 h (measured on
    // spheres and planes), and a plain shift would subtract that from
    // every distance. So the far field takes its constant from the two
    // rings around the source, where geodesic = Euclidean distance to
    // O(h^3), and the shift blends to the source value within ~h.
    double source_value = 0.0, weight_sum = 0.0;
    Eigen::RowVector3d source_point = Eigen::RowVector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      const int v = placed.corners[ci][static_cast<std::size_t>(k)];
      if (d.component[static_cast<std::size_t>(v)] != comp) continue;
      source_value += placed.weights[ci](k) * phi(v, c);
      source_point += placed.weights[ci](k) * d.positions.row(v);
      weight_sum += placed.weights[ci](k);
    }
    if (weight_sum != 0.0) {
      source_value /= weight_sum;
      source_point /= weight_sum;
    }
    const std::vector<int> ring = ringsAround(d, placed.corners[ci], comp);
    double far_value = source_value;
    if (!ring.empty()) {
      far_value = 0.0;
      for (int v : ring) far_value += phi(v, c) - (d.positions.row(v) - source_point).norm();
      far_value /= static_cast<double>(ring.size());
    }
    out.points.row(c) = source_point;
    out.values(c) = source_value;
    out.far_values(c) = far_value;
    out.components[ci] = comp;
  }
  return out;
}

// Shift so the source is at 0, clamp, +Inf off the source's component: rows
// s0.. of `out` (#sources by #V, original vertex order). Vertex-major so the
// block's sources are adjacent in `out` (column-major).
void writeDistances(const GeodesicSolver::Data& d, const Block& phi, const SourceShifts& shifts, Eigen::Index s0,
                    Eigen::MatrixXd& out) {
  const Eigen::Index w = phi.cols();
  const double inv_h2 = 1.0 / (d.mean_edge * d.mean_edge);
  constexpr double kBlendCutoff = 36.0;  // (distance / h)^2 beyond which exp(-x) < 3e-16
  for (Eigen::Index v = 0; v < d.vertex_count; ++v) {
    const int p = d.order[static_cast<std::size_t>(v)];
    const int vertex_component = d.component[static_cast<std::size_t>(p)];
    for (Eigen::Index c = 0; c < w; ++c) {
      const int comp = shifts.components[static_cast<std::size_t>(c)];
      double& result = out(s0 + c, v);
      if (comp < 0 || vertex_component != comp) {
        result = comp == -2 ? std::numeric_limits<double>::quiet_NaN() : kInf;
        continue;
      }
      const double x2 = (d.positions.row(p) - shifts.points.row(c)).squaredNorm() * inv_h2;
      const double blend = x2 < kBlendCutoff ? std::exp(-x2) : 0.0;
      result = std::max(0.0, phi(p, c) - (blend * shifts.values(c) + (1.0 - blend) * shifts.far_values(c)));
    }
  }
}

}  // namespace

Eigen::MatrixXd GeodesicSolver::distances(const std::vector<SurfacePoint>& sources) const {
  const Data& d = *data_;
  const auto ns = static_cast<Eigen::Index>(sources.size());
  Eigen::MatrixXd out(ns, d.vertex_count);
  const SourceBlocks blocks = sourceBlocks(ns);
  parallelFor(blocks.count, [&](std::ptrdiff_t block_begin, std::ptrdiff_t block_end) {
    for (std::ptrdiff_t b = block_begin; b < block_end; ++b) {
      const Eigen::Index s0 = blocks.start(b);
      const std::span<const SurfacePoint> block_sources(sources.data() + s0,
                                                        static_cast<std::size_t>(blocks.start(b + 1) - s0));
      const PlacedSources placed = placeSources(d, block_sources);
      const Block u = flowHeat(d, placed.heat);
      const Block phi = solvePoisson(d, integratedDivergence(d, u));
      writeDistances(d, phi, sourceShifts(d, block_sources, placed, phi), s0, out);
    }
  }, 1);
  return out;
}

}  // namespace core
