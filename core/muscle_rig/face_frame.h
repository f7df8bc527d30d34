// The face's own frame and size, found from its 68 iBUG landmarks, so the
// reference muscle rig (muscle_rig.h) places every point relative to the
// face and never to a fixed scale: right = towards the subject's left eye
// corner, up = from mouth to eyes, forward = out of the face; distances in
// units of the inter-ocular distance (outer eye corners).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"
#include "core/geometry/mesh.h"
#include "core/geometry/point_cloud_index.h"
#include "core/io/landmarks.h"

namespace core {

struct FaceFrame {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // between the outer eye corners, model units
  Eigen::Vector3d right = Eigen::Vector3d::UnitX();  // unit, towards the subject's left (+X in glTF heads)
  Eigen::Vector3d up = Eigen::Vector3d::UnitY();     // unit
  Eigen::Vector3d forward = Eigen::Vector3d::UnitZ();  // unit, out of the face
  double iod = 1.0;                                  // inter-ocular distance, model units (> 0)
  std::map<std::string, Eigen::Vector3d> landmarks;  // resolved positions by name
  std::shared_ptr<const PointCloudIndex> vertices;   // the face's vertices (shared: frames are copied)

  // p in frame coordinates (x right, y up, z forward), in units of iod.
  Eigen::Vector3d toFrame(const Eigen::Vector3d& p) const;
  // The model point at frame coordinates `local` (units of iod).
  Eigen::Vector3d toModel(const Eigen::Vector3d& local) const;
  // A landmark's position; asserts it exists (buildFaceFrame checked the names).
  const Eigen::Vector3d& at(const std::string& name) const;
  // The landmark moved by (x, y, z) iod along (side * right, up, forward).
  Eigen::Vector3d offset(const std::string& name, int side, double x, double y, double z = 0.0) const;
  // The face's vertex nearest to `point` (ties: the lower index).
  int nearestVertex(const Eigen::Vector3d& point) const;
};

// Every landmark name the muscle rig reads (the 68 iBUG names as written by
// the ICT landmark file and core/synthetic).
const std::vector<std::string>& muscleRigLandmarkNames();

// Errors: a missing landmark (named, with `label`), landmarks off the mesh,
// coincident eye corners or mouth at the eyes' height.
Result<FaceFrame> buildFaceFrame(const Mesh& face, const LandmarkSet& landmarks, const std::string& label);

// The mouth line of the face: between the inner lip contours (landmarks
// 60-67), y (frame units) as a function of x, held flat past the corners.
struct MouthLine {
  std::vector<double> x, y;  // increasing x
  double heightAt(double x_frame) const;
};
MouthLine buildMouthLine(const FaceFrame& frame);

}  // namespace core
