// core::Rig: a skinned, morphed, animated mesh with per-vertex attributes, as
// read from and written to glTF (core/io/gltf_*.cpp). Plain data; every stage of
// the transfer reads one and returns another.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>

#include "core/geometry/mesh.h"
#include "core/rig/material.h"

namespace core {

// A scene node (joints are nodes). Rest pose = its local TRS.
struct Node {
  std::string name;
  int parent = -1;                                             // node index, -1 for a root
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();       // model units
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
};

struct Skin {
  std::string name;
  std::vector<int> joints;                   // node indices; JOINTS_n values index this list
  std::vector<Eigen::Matrix4d> inverse_bind; // one per joint (bottom row 0 0 0 1)
  int skeleton = -1;                         // optional root node, -1 = unset
};

// Per-vertex influences, any number per vertex: #V by #joints, row-major,
// rows non-negative and summing to 1 for skinned vertices.
using SkinWeights = Eigen::SparseMatrix<double, Eigen::RowMajor>;

struct MorphTarget {
  std::string name;                 // from mesh.extras.targetNames (or "target_<i>")
  Eigen::MatrixX3d position_deltas; // #V by 3, model units (dense in memory; written sparse)
  Eigen::MatrixX3d normal_deltas;   // #V by 3, or 0 rows when absent
};

enum class Interpolation { kLinear, kStep, kCubicSpline };
enum class AnimationPath { kTranslation, kRotation, kScale, kWeights };

struct AnimationChannel {
  int node = -1;                    // target node index
  AnimationPath path = AnimationPath::kTranslation;
  Interpolation interpolation = Interpolation::kLinear;
  Eigen::VectorXd times;            // #K key times, seconds, increasing
  // #K (x3 for cubic spline: in-tangent, value, out-tangent per key, glTF order)
  // by components: 3 (translation, scale), 4 (rotation quaternion x y z w),
  // or #morph targets (weights).
  Eigen::MatrixXd values;
};

struct Animation {
  std::string name;
  std::vector<AnimationChannel> channels;
};

// Movement exaggeration (papers 000 sec. 5.4.2): one gain for everything, or
// the one given by name (a morph target's, a joint's).
struct Exaggeration {
  double gain = 1.0;
  std::map<std::string, double> by_name;
  double of(const std::string& name) const {
    const auto found = by_name.find(name);
    return found != by_name.end() ? found->second : gain;
  }
};

// Vertex attributes beyond positions/normals/TEXCOORD_0 (which live in Mesh).
struct VertexAttributes {
  std::vector<Eigen::MatrixX2d> extra_uv_sets;     // TEXCOORD_1.. (#V by 2 each)
  Eigen::MatrixX4d colors;                         // COLOR_0 as RGBA in [0,1], or 0 rows
  std::map<std::string, Eigen::VectorXi> labels;   // integer custom attributes "_NAME" (SCALAR)
  std::map<std::string, Eigen::MatrixXd> fields;   // float custom attributes "_NAME": #V by 1..4
};

// A mesh of the rig besides the face (eyeballs, teeth, tongue, lashes): its
// own geometry, shapes and attributes, skinned (or not) like the face, to the
// rig's skin. Carried by transfer and fit, written back with its name.
struct RigPart {
  std::string name;                  // the glTF mesh's name
  Mesh mesh;                         // as the face's: bind space when skinned, world space when not
  int node = -1;                     // node instancing it (Rig::nodes)
  SkinWeights weights;               // #V by rig.skin->joints.size(); empty when unskinned
  std::vector<MorphTarget> morph_targets;
  Eigen::VectorXd morph_default_weights;
  VertexAttributes attributes;
  std::vector<int> triangle_materials;  // as Rig::triangle_materials
};

struct Rig {
  Mesh mesh;                        // skinned: positions in bind space (the node transform is ignored)
  std::string mesh_name;
  std::vector<Node> nodes;          // every node of the scene, parents before children not required
  int mesh_node = -1;               // node instancing the mesh (-1: none in the file; one is made on write)
  std::optional<Skin> skin;
  SkinWeights weights;              // #V by skin->joints.size(); empty when no skin
  std::vector<MorphTarget> morph_targets;
  Eigen::VectorXd morph_default_weights;  // #targets (mesh.weights), zeros when absent
  std::vector<Animation> animations;
  VertexAttributes attributes;
  // The rig's other meshes. Weight channels of animations may target their
  // nodes (columns: that part's morph targets).
  std::vector<RigPart> parts;
  // Names of the face's morph targets that are baked presets of its
  // components (core/components/bake.h); the GLB's mesh.extras.
  std::vector<std::string> baked_presets;
  // Materials of the face and the parts, and the images their textures use.
  std::vector<Material> materials;
  std::vector<TextureImage> images;
  // Per triangle of the face, its material (index into `materials`, -1:
  // none); empty when the mesh has no material. Triangles keep their order
  // through every job, so this carries over as it is.
  std::vector<int> triangle_materials;
};

// The part as a rig of its own (its mesh, weights, shapes, attributes and
// triangle materials, with the rig's nodes, skin and no animations; its
// material indices still index the whole rig's materials): for what reads or
// writes one mesh.
Rig partAsRig(const Rig& rig, const RigPart& part);

// Appends one vertex per entry of `copy_of`, a copy of that vertex: every
// per-vertex array of the rig (mesh positions, normals, UVs, regions; skin
// weights; morph deltas; attributes) grows by copy_of.size() rows. Triangles
// are left to the caller, which re-points the corners that take the copies.
void appendVertexCopies(Rig& rig, const std::vector<int>& copy_of);

// Joint world (global rest) transforms from the nodes' local TRS: #nodes 4x4.
std::vector<Eigen::Matrix4d> nodeWorldTransforms(const std::vector<Node>& nodes);

// World transforms at rest of the rig's named nodes but the face's own node
// (its joints and the nodes parts hang from), by name.
std::map<std::string, Eigen::Matrix4d> namedNodeTransforms(const Rig& rig);

// The face's skin weight on each named joint of its skin: #V per joint
// name (none when the face is not skinned).
std::map<std::string, Eigen::VectorXd> faceJointWeights(const Rig& rig);

}  // namespace core
