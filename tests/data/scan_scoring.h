// Scoring a fit of the reference face (ICT) against a scan's true fit
// (../shared/data/scans, MANIFEST.md there; docs/FIT.md section 4, Tests), and
// the blend-shape error E the data tests share. Vertex i of a fit and of the
// truth are the same reference vertex, so every error is a per-vertex
// distance |fitted_i - truth_i|, converted to millimetres by the scan's unit
// as scans.json gives it (never by a unit the fit detected).
//
// The regions are computed once on the reference, in its own units
// (centimetres for ICT):
// - expressive face: vertices within 3 cm of an inner landmark (the 68 minus
//   the 17 jaw_*: brows, nose, eyes, mouth);
// - skin: vertices on a triangle (all 11,248 of ICT's);
// - landmarks: the reference's landmark vertices;
// - rims: the boundary loops inside the expressive face (the mouth and the
//   two eyes, not the neck cut) plus the vertices of the lips that touch at
//   rest: pairs of vertices more than 4 rings apart and closer than 1 mm.
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"
#include "core/geometry/mesh.h"
#include "core/io/landmarks.h"
#include "core/rig/rig.h"

namespace rigport_test {

// Blend-shape error per shape: E = sum_v |d_out - d_truth| / sum_v |d_truth|.
struct ShapeErrors {
  std::vector<double> per_shape;
  bool empty() const { return per_shape.empty(); }
  double median() const;  // sorted[n / 2]
  double p95() const;     // sorted[floor(0.95 n)]
  double worst() const;
};

// Shapes paired by index (the same count: throws std::invalid_argument
// otherwise). A true shape that moves nothing scores 0 when the output does
// not move either, infinity when it does.
ShapeErrors shapeErrors(std::span<const core::MorphTarget> out, std::span<const core::MorphTarget> truth);
ShapeErrors shapeErrors(const core::Rig& out, const core::Rig& truth);

// One scan of ../shared/data/scans, as scans.json describes it.
struct ScanCase {
  std::string name;                 // "scan_s01"
  std::filesystem::path scan;       // the mesh or point cloud
  std::filesystem::path landmarks;  // NAME.landmarks.json (position landmarks, scan units)
  std::filesystem::path gt;         // NAME.gt.glb: the true fit, reference topology, scan frame and units
  std::string unit;                 // "mm", "cm", "m" (scans.json "unit")
  double unit_mm = 1.0;             // millimetres per scan unit
  bool point_cloud = false;         // scans.json "format": "cloud" (no triangles)
};

// Millimetres per unit: mm 1, cm 10, m 1000, in 25.4; 0 for any other name.
double millimetresPerUnit(std::string_view unit);

// The cases of `scans_dir`/scans.json in name order, files as paths under
// `scans_dir`. Errors: the file unreadable or not JSON, a case without
// "file", "landmarks", "gt" or a known "unit".
core::Result<std::vector<ScanCase>> readScanCases(const std::filesystem::path& scans_dir);

// The case named `name`, or null.
const ScanCase* findScanCase(const std::vector<ScanCase>& cases, std::string_view name);

struct RegionOptions {
  double face_radius = 3.0;        // expressive face: within this of an inner landmark, reference units (cm)
  double contact_distance = 0.1;   // touching lips: vertices closer than this, reference units (1 mm)
  int contact_min_rings = 4;       // ... and more than this many rings apart
};

// Vertex sets of the reference the scores are taken over (ascending indices).
struct ScoringRegions {
  std::vector<int> face;                     // the expressive face
  std::vector<int> skin;                     // on a triangle
  std::vector<int> landmarks;                // the landmark vertices, in the landmark set's order
  std::vector<std::vector<int>> rim_loops;   // boundary loops inside the expressive face, longest first
  std::vector<std::array<int, 2>> lip_pairs; // vertices touching at rest (first < second), ascending
  std::vector<int> rims;                     // the rim loops' vertices and the lip pairs'
};

// The regions of `reference` (a triangle mesh) with its `landmarks` (names as
// the 68 of Multi-PIE: those starting "jaw_" are not inner). Errors: the
// landmarks do not resolve on the mesh.
core::Result<ScoringRegions> computeScoringRegions(const core::Mesh& reference, const core::LandmarkSet& landmarks,
                                                   const RegionOptions& options = {});

struct ErrorStats {
  double median = 0.0, p95 = 0.0, max = 0.0;  // millimetres; sorted[n / 2], sorted[floor(0.95 n)], largest
};

struct FitScore {
  ErrorStats face;        // the expressive face
  ErrorStats skin;        // every vertex on a triangle
  ErrorStats landmarks;   // the landmark vertices
  ErrorStats rims;        // mouth and eye rims and the touching lips
  int flipped = 0;        // triangles whose orientation flips against the truth (countFolds(truth, fitted))
  int collapsed = 0;      // triangles degenerate in the fit but not in the truth
  ShapeErrors shapes;     // E per shape; empty when no shapes were scored
};

// The fit's shapes and the true ones, paired by index.
struct ShapeSets {
  std::span<const core::MorphTarget> fitted;
  std::span<const core::MorphTarget> truth;
};

// `fitted_positions` and `gt_positions`: #V by 3 (the reference's vertex
// count), scan units; `triangles`: the reference's; `unit_mm`: millimetres per
// scan unit. Throws std::invalid_argument when the row counts differ.
FitScore scoreFit(const ScoringRegions& regions, const Eigen::MatrixX3d& fitted_positions,
                  const Eigen::MatrixX3d& gt_positions, const Eigen::MatrixX3i& triangles, double unit_mm,
                  const std::optional<ShapeSets>& shapes = std::nullopt);

// One line, no newline: "[ label ] mm: face median/p95/max | skin
// median/p95/max | landmarks median/max | rims median | flipped N collapsed N",
// then " | E median/p95/worst (n shapes)" when shapes were scored.
std::string formatFitScore(std::string_view label, const FitScore& score);
// That line on stdout, with a newline.
void printFitScore(std::string_view label, const FitScore& score);

}  // namespace rigport_test
