// Bindings resolved on a mesh, channel names, presets. Validation is in
// components_validate.cpp.
#include "core/components/components.h"

#include <cassert>
#include <cmath>

#include "core/geometry/mesh.h"

namespace core {

Binding Binding::atPosition(const Eigen::Vector3d& p) {
  Binding b;
  b.kind = BindingKind::kPosition;
  b.position = p;
  return b;
}

Binding Binding::atVertex(int v) {
  Binding b;
  b.kind = BindingKind::kVertex;
  b.vertex = v;
  return b;
}

Binding Binding::onFace(int f, const Eigen::Vector3d& barycentric) {
  Binding b;
  b.kind = BindingKind::kFace;
  b.face = f;
  b.barycentric = barycentric;
  return b;
}

Eigen::Vector3d resolveBinding(const Binding& binding, const Eigen::MatrixX3d& positions,
                               const Eigen::MatrixX3i& triangles) {
  switch (binding.kind) {
    case BindingKind::kPosition: return binding.position;
    case BindingKind::kVertex:
      assert(binding.vertex >= 0 && binding.vertex < positions.rows());
      return positions.row(binding.vertex).transpose();
    case BindingKind::kFace:
      assert(binding.face >= 0 && binding.face < triangles.rows());
      return interpolateOnFace(positions, triangles, binding.face, binding.barycentric).transpose();
  }
  return binding.position;
}

const char* clusterChannelName(ClusterChannel channel) {
  switch (channel) {
    case ClusterChannel::kTranslateX: return "translate_x";
    case ClusterChannel::kTranslateY: return "translate_y";
    case ClusterChannel::kTranslateZ: return "translate_z";
    case ClusterChannel::kRotateX: return "rotate_x";
    case ClusterChannel::kRotateY: return "rotate_y";
    case ClusterChannel::kRotateZ: return "rotate_z";
    case ClusterChannel::kScaleX: return "scale_x";
    case ClusterChannel::kScaleY: return "scale_y";
    case ClusterChannel::kScaleZ: return "scale_z";
    case ClusterChannel::kScale: return "scale";
  }
  return "?";
}

const char* jointChannelName(JointChannel channel) {
  switch (channel) {
    case JointChannel::kRotateX: return "rotate_x";
    case JointChannel::kRotateY: return "rotate_y";
    case JointChannel::kRotateZ: return "rotate_z";
  }
  return "?";
}

Result<std::map<std::string, double>> presetControls(const ComponentsDocument& doc, const std::string& name) {
  const auto found = doc.presets.find(name);
  if (found == doc.presets.end()) {
    std::vector<std::string> names;
    for (const auto& [preset_name, preset] : doc.presets) names.push_back(preset_name);
    return makeError(ErrorCode::kInvalidArgument, "presets: no preset \"" + name + "\"" + didYouMean(name, names));
  }
  std::map<std::string, double> values;
  for (const Control& control : doc.controls) values[control.name] = control.default_value;
  for (const auto& [control, value] : found->second.controls) {
    if (!values.count(control)) {
      return makeError(ErrorCode::kInvalidArgument,
                       "presets \"" + name + "\": unknown control \"" + control + "\"");
    }
    values[control] = value;
  }
  return values;
}

Status validate(const ComponentsDocument& doc, long long vertex_count) {
  ComponentsMeshCounts counts;
  counts.vertex_count = vertex_count;
  return validateComponents(doc, "components", counts);
}

}  // namespace core
