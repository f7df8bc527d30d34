// The transfer's check of its own output: a studio TD judges a rig by its
// worst vertex (a lip vertex left hanging in the open mouth reads as a fang),
// which no median shows. Per shape, a target vertex whose delta disagrees with
// its one-ring far beyond the ring's own motion is an outlier; per vertex, a
// location (so its weights and deltas) on the other side of an opening than
// the vertex is a crossing. Reported as data (TransferReport::quality), as a
// per-vertex field (_QUALITY) on request, and, with `strict`, as a failed job.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/correspond/correspondence.h"
#include "core/rig/rig.h"

namespace core {

struct QualityOptions {
  // Outlier of a shape: a delta farther than this fraction of its ring's largest motion from every neighbour's.
  double outlier_ratio = 0.7;
  // ... and farther than this factor times the sharpest the source shape is itself where the vertex lies.
  double source_factor = 1.5;
  // Rings moving less than this fraction of the shape's largest |delta| are not judged.
  double min_motion = 0.25;
  int worst_count = 10;  // how many of the worst vertices the report lists
};

struct QualityVertex {
  int vertex = -1;
  std::string shape;   // the shape it is worst in ("" for a crossing)
  double score = 0.0;  // |delta - ring mean| / ring's largest motion (a crossing: 1)
};

struct ShapeOutliers {
  std::string shape;
  int vertices = 0;    // outlier vertices in this shape
  double worst = 0.0;  // largest score in it
};

struct QualityReport {
  int shape_outliers = 0;              // outlier (shape, vertex) pairs over all shapes
  std::vector<ShapeOutliers> shapes;   // the shapes with any, in the rig's order
  // Target vertices on one side of an opening located on the other side's
  // source faces (their weights and deltas come from across the mouth or an
  // eye), and those inpainted where the inpainting reached across.
  int crossed_vertices = 0;
  std::vector<ShapeOutliers> crossed_shapes;  // the shapes those vertices move in (worst: largest |delta| / shape's largest)
  // Vertices of low confidence found unsure and repaired (their deltas
  // inpainted from their neighbours) before this report was made (transferRig).
  int repaired_vertices = 0;
  std::vector<QualityVertex> worst;    // the worst outliers and crossings, worst first
  // #Vt: per vertex, how many shapes it is an outlier in, plus one when it
  // crossed an opening (the _QUALITY attribute).
  Eigen::VectorXd per_vertex;
  bool clean() const { return shape_outliers == 0 && crossed_vertices == 0; }
  // "mouthClose (2 vertices), jawOpen (2 vertices); 1 vertex located across
  // an opening (the other lip or lid), moving in jawOpen (1)"
  std::string summary() const;
};

// The source side of the check: its faces (the locations refer to them),
// vertex adjacency, openingSides (empty: none), and its own shapes (in the
// order of the transferred ones), to judge a flagged vertex against what
// the rig itself does there.
struct QualitySource {
  const Eigen::MatrixX3i& triangles;
  const VertexAdjacency& adjacency;
  const std::vector<int>& sides;
  const std::vector<MorphTarget>& shapes;
};

// target: the output mesh (its own vertices) and target_adjacency its
// vertexAdjacency; shapes: the transferred morph targets (#Vt rows, in the
// rig's order); target_sides: openingSides of the target, numbered as the
// source's (empty when the openings were not matched with sides).
QualityReport checkTransferQuality(const Mesh& target, const VertexAdjacency& target_adjacency,
                                   const std::vector<MorphTarget>& shapes, const TargetLocations& locations,
                                   const std::vector<int>& target_sides, const QualitySource& source,
                                   const QualityOptions& options = {});

}  // namespace core
