#include "tests/data/scan_scoring.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "core/correspond/correspondence.h"

namespace rigport_test {
namespace {

// sorted[min(n - 1, floor(q n))] of a sorted, non-empty vector.
double sortedQuantile(const std::vector<double>& sorted, double q) {
  const auto at = static_cast<std::size_t>(q * static_cast<double>(sorted.size()));
  return sorted[std::min(sorted.size() - 1, at)];
}

std::vector<double> sortedCopy(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values;
}

ErrorStats errorStats(const Eigen::VectorXd& distance_mm, const std::vector<int>& vertices) {
  if (vertices.empty()) return {};
  std::vector<double> d;
  d.reserve(vertices.size());
  for (int v : vertices) d.push_back(distance_mm(v));
  std::sort(d.begin(), d.end());
  return {sortedQuantile(d, 0.5), sortedQuantile(d, 0.95), d.back()};
}

std::vector<int> indicesOf(const std::vector<char>& mask) {
  std::vector<int> indices;
  for (std::size_t v = 0; v < mask.size(); ++v) {
    if (mask[v]) indices.push_back(static_cast<int>(v));
  }
  return indices;
}

// Pairs of vertices on a triangle closer than `distance` and more than
// `min_rings` rings apart (lips that touch at rest, not neighbours).
std::vector<std::array<int, 2>> touchingPairs(const core::Mesh& mesh, const std::vector<char>& on_skin,
                                              double distance, int min_rings) {
  std::vector<int> order = indicesOf(on_skin);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return mesh.positions(a, 0) < mesh.positions(b, 0); });
  const core::VertexAdjacency adjacency = core::vertexAdjacency(mesh.triangles, mesh.vertexCount());
  // Breadth-first rings from one vertex, stamped so that no array is cleared.
  std::vector<int> stamp(static_cast<std::size_t>(mesh.vertexCount()), -1);
  std::vector<int> frontier, next;
  const auto withinRings = [&](int from, int to, int call) {
    frontier.assign(1, from);
    stamp[static_cast<std::size_t>(from)] = call;
    for (int ring = 0; ring < min_rings && !frontier.empty(); ++ring) {
      next.clear();
      for (int v : frontier) {
        for (int k = adjacency.offsets[static_cast<std::size_t>(v)]; k < adjacency.offsets[static_cast<std::size_t>(v) + 1]; ++k) {
          const int w = adjacency.indices[static_cast<std::size_t>(k)];
          if (stamp[static_cast<std::size_t>(w)] == call) continue;
          if (w == to) return true;
          stamp[static_cast<std::size_t>(w)] = call;
          next.push_back(w);
        }
      }
      std::swap(frontier, next);
    }
    return false;
  };
  std::vector<std::array<int, 2>> pairs;
  int call = 0;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const int a = order[i];
    for (std::size_t j = i + 1; j < order.size(); ++j) {
      const int b = order[j];
      if (mesh.positions(b, 0) - mesh.positions(a, 0) >= distance) break;
      if ((mesh.positions.row(a) - mesh.positions.row(b)).norm() >= distance) continue;
      if (withinRings(a, b, call++)) continue;
      pairs.push_back({std::min(a, b), std::max(a, b)});
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace

double ShapeErrors::median() const { return sortedQuantile(sortedCopy(per_shape), 0.5); }
double ShapeErrors::p95() const { return sortedQuantile(sortedCopy(per_shape), 0.95); }
double ShapeErrors::worst() const { return *std::max_element(per_shape.begin(), per_shape.end()); }

ShapeErrors shapeErrors(std::span<const core::MorphTarget> out, std::span<const core::MorphTarget> truth) {
  if (out.size() != truth.size()) {
    throw std::invalid_argument("shapeErrors: " + std::to_string(out.size()) + " shapes scored against " +
                                std::to_string(truth.size()));
  }
  ShapeErrors errors;
  for (std::size_t k = 0; k < truth.size(); ++k) {
    const auto& d = out[k].position_deltas;
    const auto& g = truth[k].position_deltas;
    const double error = (d - g).rowwise().norm().sum(), motion = g.rowwise().norm().sum();
    errors.per_shape.push_back(motion > 0.0 ? error / motion
                                            : (error > 0.0 ? std::numeric_limits<double>::infinity() : 0.0));
  }
  return errors;
}

ShapeErrors shapeErrors(const core::Rig& out, const core::Rig& truth) {
  return shapeErrors(out.morph_targets, truth.morph_targets);
}

double millimetresPerUnit(std::string_view unit) {
  if (unit == "mm") return 1.0;
  if (unit == "cm") return 10.0;
  if (unit == "m") return 1000.0;
  if (unit == "in") return 25.4;
  return 0.0;
}

core::Result<std::vector<ScanCase>> readScanCases(const std::filesystem::path& scans_dir) {
  const std::filesystem::path file = scans_dir / "scans.json";
  std::ifstream in(file, std::ios::binary);
  if (!in) return core::makeError(core::ErrorCode::kIo, file.string() + ": cannot be read");
  std::stringstream text;
  text << in.rdbuf();
  const nlohmann::json json = nlohmann::json::parse(text.str(), nullptr, /*allow_exceptions=*/false);
  if (!json.is_object()) return core::makeError(core::ErrorCode::kParse, file.string() + ": not a JSON object");
  std::vector<ScanCase> cases;
  for (const auto& [name, entry] : json.items()) {  // nlohmann's objects iterate in key order
    const auto text_field = [&](const char* key) -> std::string {
      return entry.contains(key) && entry[key].is_string() ? entry[key].get<std::string>() : std::string();
    };
    ScanCase scan;
    scan.name = name;
    scan.unit = text_field("unit");
    scan.unit_mm = millimetresPerUnit(scan.unit);
    const std::string scan_file = text_field("file"), landmarks = text_field("landmarks"), gt = text_field("gt");
    if (scan_file.empty() || landmarks.empty() || gt.empty() || scan.unit_mm == 0.0) {
      return core::makeError(core::ErrorCode::kParse, file.string() + ": " + name +
                                                          " lacks \"file\", \"landmarks\", \"gt\" or a known \"unit\"");
    }
    scan.scan = scans_dir / scan_file;
    scan.landmarks = scans_dir / landmarks;
    scan.gt = scans_dir / gt;
    scan.point_cloud = text_field("format") == "cloud";
    cases.push_back(std::move(scan));
  }
  return cases;
}

const ScanCase* findScanCase(const std::vector<ScanCase>& cases, std::string_view name) {
  for (const ScanCase& scan : cases) {
    if (scan.name == name) return &scan;
  }
  return nullptr;
}

core::Result<ScoringRegions> computeScoringRegions(const core::Mesh& reference, const core::LandmarkSet& landmarks,
                                                   const RegionOptions& options) {
  auto positions = core::resolveLandmarks(landmarks, reference, "scoring reference");
  if (!positions) return positions.error();
  const Eigen::Index n = reference.vertexCount();
  ScoringRegions regions;
  regions.landmarks = core::landmarkVertices(landmarks, reference, *positions);
  if (std::find(regions.landmarks.begin(), regions.landmarks.end(), -1) != regions.landmarks.end()) {
    return core::makeError(core::ErrorCode::kInvalidLandmarks, "scoring reference: a landmark stands for no vertex");
  }

  std::vector<char> on_skin(static_cast<std::size_t>(n), 0);
  for (Eigen::Index f = 0; f < reference.triangleCount(); ++f) {
    for (int k = 0; k < 3; ++k) on_skin[static_cast<std::size_t>(reference.triangles(f, k))] = 1;
  }
  regions.skin = indicesOf(on_skin);

  std::vector<Eigen::RowVector3d> inner;
  for (std::size_t l = 0; l < landmarks.landmarks.size(); ++l) {
    if (!landmarks.landmarks[l].name.starts_with("jaw_")) inner.push_back(positions->row(static_cast<Eigen::Index>(l)));
  }
  std::vector<char> in_face(static_cast<std::size_t>(n), 0);
  const double r2 = options.face_radius * options.face_radius;
  for (Eigen::Index v = 0; v < n; ++v) {
    for (const Eigen::RowVector3d& p : inner) {
      if ((reference.positions.row(v) - p).squaredNorm() <= r2) {
        in_face[static_cast<std::size_t>(v)] = 1;
        break;
      }
    }
  }
  regions.face = indicesOf(in_face);

  std::vector<char> on_rim(static_cast<std::size_t>(n), 0);
  for (const core::BoundaryLoop& loop : core::boundaryLoops(reference)) {
    const bool inside = std::all_of(loop.vertices.begin(), loop.vertices.end(),
                                    [&](int v) { return in_face[static_cast<std::size_t>(v)] != 0; });
    if (!inside) continue;  // the neck cut
    regions.rim_loops.push_back(loop.vertices);
    for (int v : loop.vertices) on_rim[static_cast<std::size_t>(v)] = 1;
  }
  regions.lip_pairs = touchingPairs(reference, on_skin, options.contact_distance, options.contact_min_rings);
  for (const auto& pair : regions.lip_pairs) {
    for (int v : pair) on_rim[static_cast<std::size_t>(v)] = 1;
  }
  regions.rims = indicesOf(on_rim);
  return regions;
}

FitScore scoreFit(const ScoringRegions& regions, const Eigen::MatrixX3d& fitted_positions,
                  const Eigen::MatrixX3d& gt_positions, const Eigen::MatrixX3i& triangles, double unit_mm,
                  const std::optional<ShapeSets>& shapes) {
  if (fitted_positions.rows() != gt_positions.rows()) {
    throw std::invalid_argument("scoreFit: " + std::to_string(fitted_positions.rows()) + " fitted vertices against " +
                                std::to_string(gt_positions.rows()) + " true ones");
  }
  const Eigen::VectorXd distance_mm = unit_mm * (fitted_positions - gt_positions).rowwise().norm();
  FitScore score;
  score.face = errorStats(distance_mm, regions.face);
  score.skin = errorStats(distance_mm, regions.skin);
  score.landmarks = errorStats(distance_mm, regions.landmarks);
  score.rims = errorStats(distance_mm, regions.rims);
  const core::FoldReport folds = core::countFolds(gt_positions, fitted_positions, triangles);
  score.flipped = folds.flipped;
  score.collapsed = folds.collapsed;
  if (shapes) score.shapes = shapeErrors(shapes->fitted, shapes->truth);
  return score;
}

std::string formatFitScore(std::string_view label, const FitScore& s) {
  char line[512];
  std::snprintf(line, sizeof line,
                "[ %-28.*s ] mm: face %.2f/%.2f/%.2f | skin %.2f/%.2f/%.2f | landmarks %.2f/%.2f | rims %.2f | "
                "flipped %d collapsed %d",
                static_cast<int>(label.size()), label.data(), s.face.median, s.face.p95, s.face.max, s.skin.median,
                s.skin.p95, s.skin.max, s.landmarks.median, s.landmarks.max, s.rims.median, s.flipped, s.collapsed);
  std::string text = line;
  if (!s.shapes.empty()) {
    std::snprintf(line, sizeof line, " | E %.4f/%.4f/%.4f (%zu shapes)", s.shapes.median(), s.shapes.p95(),
                  s.shapes.worst(), s.shapes.per_shape.size());
    text += line;
  }
  return text;
}

void printFitScore(std::string_view label, const FitScore& score) {
  std::printf("%s\n", formatFitScore(label, score).c_str());
}

}  // namespace rigport_test
