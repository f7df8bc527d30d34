// glTF rig reading, the rest: morph targets, animations, vertex attributes,
// the size check before any of it. readRig.

#include "core/io/gltf_model.h"

namespace core::gltf {

std::vector<std::string> targetNames(const tinygltf::Mesh& gmesh, std::size_t count, const std::string& mesh_name,
                                     std::vector<std::string>& warnings) {
  std::vector<std::string> names(count);
  for (std::size_t i = 0; i < count; ++i) names[i] = "target_" + std::to_string(i);
  if (!gmesh.extras.IsObject() || !gmesh.extras.Has("targetNames")) return names;
  const tinygltf::Value& list = gmesh.extras.Get("targetNames");
  bool usable = list.IsArray() && list.ArrayLen() == count;
  for (std::size_t i = 0; usable && i < count; ++i) usable = list.Get(static_cast<int>(i)).IsString();
  if (!usable) {
    warnings.push_back(mesh_name + " extras.targetNames is not a list of " + std::to_string(count) +
                       " strings; targets named target_<i>");
    return names;
  }
  for (std::size_t i = 0; i < count; ++i) names[i] = list.Get(static_cast<int>(i)).Get<std::string>();
  return names;
}

namespace {

// Morph targets merged across primitives (POSITION and NORMAL deltas).
Result<std::vector<MorphTarget>> readMorphTargets(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                                  const std::vector<PrimitiveRange>& ranges,
                                                  const std::string& mesh_name, const std::string& label,
                                                  std::vector<std::string>& warnings) {
  const std::size_t count = gmesh.primitives.front().targets.size();
  for (std::size_t p = 1; p < gmesh.primitives.size(); ++p) {
    if (gmesh.primitives[p].targets.size() != count) {
      return makeError(ErrorCode::kUnsupported, label + ": " + mesh_name + " primitive " + std::to_string(p) + " has " +
                                                    std::to_string(gmesh.primitives[p].targets.size()) +
                                                    " morph targets but primitive 0 has " + std::to_string(count));
    }
  }
  const std::vector<std::string> names = targetNames(gmesh, count, mesh_name, warnings);
  std::set<std::string> ignored;
  std::vector<MorphTarget> targets(count);
  for (std::size_t t = 0; t < count; ++t) {
    const int ti = static_cast<int>(t);
    const std::string role = "morph target " + std::to_string(t);
    auto positions = readMergedAttribute<Eigen::MatrixX3d>(model, attributeAccessors(gmesh, "POSITION", ti), ranges,
                                                           3, role + " POSITION", mesh_name, label);
    if (!positions) return positions.error();
    auto normals = readMergedAttribute<Eigen::MatrixX3d>(model, attributeAccessors(gmesh, "NORMAL", ti), ranges, 3,
                                                         role + " NORMAL", mesh_name, label);
    if (!normals) return normals.error();
    MorphTarget& target = targets[t];
    target.name = names[t];
    if (positions->rows() > 0) {
      target.position_deltas = std::move(*positions);
    } else {
      target.position_deltas = Eigen::MatrixX3d::Zero(vertexTotal(ranges), 3);  // NORMAL-only target
    }
    if (normals->rows() > 0) target.normal_deltas = std::move(*normals);  // else 0 rows: no NORMAL deltas
    for (const tinygltf::Primitive& primitive : gmesh.primitives) {
      for (const auto& [name, accessor] : primitive.targets[t]) {
        if (name != "POSITION" && name != "NORMAL") ignored.insert(name);
      }
    }
  }
  for (const std::string& name : ignored) warnings.push_back("morph target " + name + " deltas ignored");
  return targets;
}

// An unskinned mesh is read in world space (placeMesh), so are its deltas:
// positions by the linear part, normals by its inverse transpose.
void transformMorphTargets(const Eigen::Matrix4d& world, std::vector<MorphTarget>& targets) {
  if (world.isIdentity(0.0)) return;
  const Eigen::Matrix3d linear = world.topLeftCorner<3, 3>();
  const Eigen::Matrix3d normal_matrix = linear.inverse().transpose();
  for (MorphTarget& target : targets) {
    target.position_deltas = (target.position_deltas * linear.transpose()).eval();
    if (target.normal_deltas.rows() > 0) {
      target.normal_deltas = (target.normal_deltas * normal_matrix.transpose()).eval();
    }
  }
}

// node.weights (which override mesh.weights, spec "Morph Targets"), else
// mesh.weights, else zeros.
Eigen::VectorXd defaultMorphWeights(const tinygltf::Mesh& gmesh, const tinygltf::Node* node, std::size_t count,
                                    const std::string& mesh_name, std::vector<std::string>& warnings) {
  Eigen::VectorXd weights = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(count));
  const std::vector<double>& source = node && !node->weights.empty() ? node->weights : gmesh.weights;
  if (source.empty()) return weights;
  const bool finite = std::all_of(source.begin(), source.end(), [](double w) { return std::isfinite(w); });
  if (source.size() != count || !finite) {
    warnings.push_back(mesh_name + " default morph weights are not " + std::to_string(count) +
                       " finite numbers; zeros used");
    return weights;
  }
  for (std::size_t i = 0; i < count; ++i) weights(static_cast<Eigen::Index>(i)) = source[i];
  return weights;
}

std::optional<AnimationPath> animationPath(const std::string& path) {
  if (path == "translation") return AnimationPath::kTranslation;
  if (path == "rotation") return AnimationPath::kRotation;
  if (path == "scale") return AnimationPath::kScale;
  if (path == "weights") return AnimationPath::kWeights;
  return std::nullopt;
}

}  // namespace

std::optional<Interpolation> interpolation(const std::string& name) {
  if (name == "LINEAR" || name.empty()) return Interpolation::kLinear;
  if (name == "STEP") return Interpolation::kStep;
  if (name == "CUBICSPLINE") return Interpolation::kCubicSpline;
  return std::nullopt;
}

namespace {

Result<Eigen::VectorXd> readKeyTimes(const tinygltf::Model& model, int accessor, const std::string& what,
                                     const std::string& label) {
  auto input = readAccessor(model, accessor, what + " input", label);
  if (!input) return input.error();
  if (input->components != 1 || input->count == 0) {
    return parseError(label, what + " input must be a non-empty SCALAR accessor");
  }
  Eigen::VectorXd times(static_cast<Eigen::Index>(input->count));
  for (std::size_t k = 0; k < input->count; ++k) {
    const double t = input->values[k];
    if (!std::isfinite(t)) return parseError(label, what + " key time " + std::to_string(k) + " is not finite");
    if (k > 0 && !(t > input->values[k - 1])) {
      return parseError(label, what + " key times do not increase at key " + std::to_string(k));
    }
    times(static_cast<Eigen::Index>(k)) = t;
  }
  return times;
}

// Rotation keys as unit quaternions, like node rotations (cubic spline
// tangents stay as they are).
Result<AnimationChannel> normalizeRotationKeys(AnimationChannel channel, const std::string& what,
                                               const std::string& label) {
  const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
  for (Eigen::Index r = cubic ? 1 : 0; r < channel.values.rows(); r += cubic ? 3 : 1) {
    const double norm = channel.values.row(r).norm();
    if (!(norm > 0.0)) return parseError(label, what + " rotation key " + std::to_string(r) + " is a zero quaternion");
    channel.values.row(r) /= norm;
  }
  return channel;
}

// One channel: key times and #K (x3 for cubic spline) by `columns` values.
Result<AnimationChannel> readChannel(const tinygltf::Model& model, const tinygltf::Animation& ganim,
                                     const tinygltf::AnimationChannel& gchannel, AnimationPath path, int columns,
                                     const std::string& what, const std::string& label) {
  if (gchannel.sampler < 0 || static_cast<std::size_t>(gchannel.sampler) >= ganim.samplers.size()) {
    return parseError(label, what + " refers to sampler " + std::to_string(gchannel.sampler) +
                                 " but the animation has " + std::to_string(ganim.samplers.size()));
  }
  const tinygltf::AnimationSampler& sampler = ganim.samplers[static_cast<std::size_t>(gchannel.sampler)];
  const auto mode = interpolation(sampler.interpolation);
  if (!mode) return parseError(label, what + " has unknown interpolation '" + sampler.interpolation + "'");
  AnimationChannel channel;
  channel.node = gchannel.target_node;
  channel.path = path;
  channel.interpolation = *mode;
  auto times = readKeyTimes(model, sampler.input, what, label);
  if (!times) return times.error();
  channel.times = std::move(*times);

  auto output = readAccessor(model, sampler.output, what + " output", label);
  if (!output) return output.error();
  const auto rows = static_cast<std::size_t>(channel.times.size()) * (*mode == Interpolation::kCubicSpline ? 3 : 1);
  const int element_components = path == AnimationPath::kWeights ? 1 : columns;
  const std::size_t expected = path == AnimationPath::kWeights ? rows * static_cast<std::size_t>(columns) : rows;
  if (output->components != element_components || output->count != expected) {
    return parseError(label, what + " output has " + std::to_string(output->count) + " elements of " +
                                 std::to_string(output->components) + " components; expected " +
                                 std::to_string(expected) + " of " + std::to_string(element_components));
  }
  channel.values.resize(static_cast<Eigen::Index>(rows), columns);
  for (std::size_t r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) {
      // Row-major either way: element r of `columns` components, or `columns` scalars per row.
      const double x = output->values[r * static_cast<std::size_t>(columns) + static_cast<std::size_t>(c)];
      if (!std::isfinite(x)) return parseError(label, what + " output value " + std::to_string(r) + " is not finite");
      channel.values(static_cast<Eigen::Index>(r), c) = x;
    }
  }
  if (path == AnimationPath::kRotation) return normalizeRotationKeys(std::move(channel), what, label);
  return channel;
}

// Every usable channel of every animation. Weight channels must target a
// mesh node of the rig (`morph_targets_of`: node -> its mesh's morph target
// count); others are skipped with a warning.
Result<std::vector<Animation>> readAnimations(const tinygltf::Model& model, const std::map<int, int>& morph_targets_of,
                                              const std::string& label, std::vector<std::string>& warnings) {
  std::vector<Animation> animations;
  for (std::size_t a = 0; a < model.animations.size(); ++a) {
    const tinygltf::Animation& ganim = model.animations[a];
    const std::string name = "animation " + std::to_string(a) + quoted(ganim.name);
    Animation animation;
    animation.name = ganim.name;
    for (std::size_t c = 0; c < ganim.channels.size(); ++c) {
      const tinygltf::AnimationChannel& gchannel = ganim.channels[c];
      const std::string what = name + " channel " + std::to_string(c);
      const int node = gchannel.target_node;
      if (node < 0) {
        warnings.push_back(what + " has no target node; skipped");
        continue;
      }
      if (static_cast<std::size_t>(node) >= model.nodes.size()) {
        return parseError(label, what + " targets node " + std::to_string(node) + " but the file has " +
                                     std::to_string(model.nodes.size()) + " nodes");
      }
      const auto path = animationPath(gchannel.target_path);
      if (!path) {
        warnings.push_back(what + " animates '" + gchannel.target_path + "', which a rig does not carry; skipped");
        continue;
      }
      const auto mesh_of_node = morph_targets_of.find(node);
      if (*path == AnimationPath::kWeights && mesh_of_node == morph_targets_of.end()) {
        warnings.push_back(what + " animates the morph weights of node " + std::to_string(node) +
                           ", not of a mesh of the rig; skipped");
        continue;
      }
      const int target_count = mesh_of_node != morph_targets_of.end() ? mesh_of_node->second : 0;
      if (*path == AnimationPath::kWeights && target_count == 0) {
        return parseError(label, what + " animates morph weights but the mesh has no morph targets");
      }
      const int columns = *path == AnimationPath::kRotation ? 4 : *path == AnimationPath::kWeights ? target_count : 3;
      auto channel = readChannel(model, ganim, gchannel, *path, columns, what, label);
      if (!channel) return channel.error();
      animation.channels.push_back(std::move(*channel));
    }
    if (animation.channels.empty()) {
      warnings.push_back(name + " has no usable channel; dropped");
      continue;
    }
    animations.push_back(std::move(animation));
  }
  return animations;
}

// TEXCOORD_1.. as far as every primitive has them.
Result<std::vector<Eigen::MatrixX2d>> readExtraUvSets(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                                      const std::vector<PrimitiveRange>& ranges,
                                                      const std::string& mesh_name, const std::string& label,
                                                      std::vector<std::string>& warnings) {
  std::vector<Eigen::MatrixX2d> sets;
  for (int k = 1;; ++k) {
    const std::string name = "TEXCOORD_" + std::to_string(k);
    const std::vector<int> accessors = attributeAccessors(gmesh, name);
    if (!presentInAny(accessors)) break;
    if (!presentInAll(accessors)) {
      warnings.push_back(name + " is missing on some primitives of " + mesh_name + "; it and later sets dropped");
      break;
    }
    auto uvs = readMergedAttribute(model, accessors, ranges, 2, name, mesh_name, label);
    if (!uvs) return uvs.error();
    sets.emplace_back(std::move(*uvs));
  }
  return sets;
}

// COLOR_0 as RGBA (VEC3 gets alpha 1); 0 rows when absent.
Result<Eigen::MatrixX4d> readColors(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                    const std::vector<PrimitiveRange>& ranges, const std::string& mesh_name,
                                    const std::string& label, std::vector<std::string>& warnings) {
  const std::vector<int> accessors = attributeAccessors(gmesh, "COLOR_0");
  if (!presentInAny(accessors)) return Eigen::MatrixX4d();
  if (!presentInAll(accessors)) {
    warnings.push_back("COLOR_0 is missing on some primitives of " + mesh_name + "; colours dropped");
    return Eigen::MatrixX4d();
  }
  auto colors = readMergedAttribute(model, accessors, ranges, 0, "COLOR_0", mesh_name, label);
  if (!colors) return colors.error();
  if (colors->cols() != 3 && colors->cols() != 4) return parseError(label, "COLOR_0 must be VEC3 or VEC4");
  Eigen::MatrixX4d rgba = Eigen::MatrixX4d::Ones(colors->rows(), 4);
  rgba.leftCols(colors->cols()) = *colors;
  return rgba;
}

}  // namespace

Status readCustomAttribute(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                           const std::vector<PrimitiveRange>& ranges, const std::string& name,
                           const std::string& mesh_name, const std::string& label, VertexAttributes& out,
                           std::vector<std::string>& warnings) {
  const std::vector<int> accessors = attributeAccessors(gmesh, name);
  if (!presentInAll(accessors)) {
    warnings.push_back(name + " is missing on some primitives of " + mesh_name + "; dropped");
    return Ok{};
  }
  auto values = readMergedAttribute(model, accessors, ranges, 0, name, mesh_name, label);
  if (!values) return values.error();
  // 1: label (unnormalised integer SCALAR), 2: field (float or normalized SCALAR..VEC4), 0: neither.
  auto kind = [&](int index) {
    const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(index)];
    const bool is_float = a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT || a.normalized;
    const bool is_vector =
        a.type == TINYGLTF_TYPE_SCALAR || (a.type >= TINYGLTF_TYPE_VEC2 && a.type <= TINYGLTF_TYPE_VEC4);
    if (!is_float) return a.type == TINYGLTF_TYPE_SCALAR ? 1 : 0;
    return is_vector ? 2 : 0;
  };
  const int first = kind(accessors.front());
  const bool same = std::all_of(accessors.begin(), accessors.end(), [&](int a) { return kind(a) == first; });
  const std::string key = name.substr(1);
  if (first == 0 || !same) {
    warnings.push_back(name + " is neither an integer SCALAR nor a float SCALAR..VEC4 on every primitive; dropped");
    return Ok{};
  }
  if (first == 2) {
    out.fields[key] = std::move(*values);
    return Ok{};
  }
  const bool fits_int = values->rows() == 0 || (values->maxCoeff() <= std::numeric_limits<int>::max() &&
                                                 values->minCoeff() >= std::numeric_limits<int>::min());
  if (!fits_int) {
    warnings.push_back(name + " has values beyond the int range; dropped");
    return Ok{};
  }
  out.labels[key] = values->col(0).cast<int>();
  return Ok{};
}

namespace {

bool isInfluenceOrBaseAttribute(const std::string& name) {
  return name == "POSITION" || name == "NORMAL" || name.rfind("TEXCOORD_", 0) == 0 || name.rfind("JOINTS_", 0) == 0 ||
         name.rfind("WEIGHTS_", 0) == 0 || name == "COLOR_0";
}

Result<VertexAttributes> readVertexAttributes(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                              const std::vector<PrimitiveRange>& ranges, const std::string& mesh_name,
                                              const std::string& label, std::vector<std::string>& warnings) {
  VertexAttributes out;
  auto uv_sets = readExtraUvSets(model, gmesh, ranges, mesh_name, label, warnings);
  if (!uv_sets) return uv_sets.error();
  out.extra_uv_sets = std::move(*uv_sets);
  auto colors = readColors(model, gmesh, ranges, mesh_name, label, warnings);
  if (!colors) return colors.error();
  out.colors = std::move(*colors);
  std::set<std::string> names;
  for (const tinygltf::Primitive& primitive : gmesh.primitives) {
    for (const auto& [name, accessor] : primitive.attributes) names.insert(name);
  }
  for (const std::string& name : names) {
    if (isInfluenceOrBaseAttribute(name)) continue;
    if (name.size() > 1 && name.front() == '_') {
      if (auto ok = readCustomAttribute(model, gmesh, ranges, name, mesh_name, label, out, warnings); !ok) {
        return ok.error();
      }
      continue;
    }
    warnings.push_back("attribute " + name + " of " + mesh_name + " is not carried by rigs; ignored");
  }
  return out;
}

// mesh.extras.rigportBakedPresets: names of morph targets of this mesh.
std::vector<std::string> bakedPresets(const tinygltf::Mesh& gmesh, const std::vector<MorphTarget>& targets,
                                      const std::string& mesh_name, std::vector<std::string>& warnings) {
  std::vector<std::string> names;
  if (!gmesh.extras.IsObject() || !gmesh.extras.Has(kBakedPresetsKey)) return names;
  const tinygltf::Value& list = gmesh.extras.Get(kBakedPresetsKey);
  for (std::size_t i = 0; list.IsArray() && i < list.ArrayLen(); ++i) {
    const tinygltf::Value& item = list.Get(static_cast<int>(i));
    const bool known = item.IsString() && std::any_of(targets.begin(), targets.end(), [&](const MorphTarget& t) {
                         return t.name == item.Get<std::string>();
                       });
    if (!known) {
      warnings.push_back(mesh_name + " extras." + kBakedPresetsKey + " is not a list of its morph target names; ignored");
      return {};
    }
    names.push_back(item.Get<std::string>());
  }
  return names;
}

Status readMorphing(const tinygltf::Model& model, const MeshChoice& choice, const std::vector<PrimitiveRange>& ranges,
                    const std::string& mesh_name, const std::string& label, Rig& rig,
                    std::vector<std::string>& warnings) {
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  auto targets = readMorphTargets(model, gmesh, ranges, mesh_name, label, warnings);
  if (!targets) return targets.error();
  rig.morph_targets = std::move(*targets);
  if (!choice.skinned && choice.node >= 0) {
    auto world = worldTransform(model, choice.node, label);
    if (!world) return world.error();
    transformMorphTargets(*world, rig.morph_targets);
  }
  const tinygltf::Node* node = choice.node >= 0 ? &model.nodes[static_cast<std::size_t>(choice.node)] : nullptr;
  rig.morph_default_weights = defaultMorphWeights(gmesh, node, rig.morph_targets.size(), mesh_name, warnings);
  rig.baked_presets = bakedPresets(gmesh, rig.morph_targets, mesh_name, warnings);
  return Ok{};
}

// A rig is dense in memory (#targets x #V x 3 morph deltas, all key values),
// and accessors without a bufferView are zeros that cost no file bytes, so a
// small file could claim far more than any face rig. Checked before reading.
constexpr std::size_t kMaxRigValues = std::size_t{1} << 27;  // 1 GiB of doubles

std::size_t accessorValueCount(const tinygltf::Model& model, int index) {
  if (index < 0 || static_cast<std::size_t>(index) >= model.accessors.size()) return 0;  // reported when read
  const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(index)];
  const auto components = static_cast<std::size_t>(typeComponents(a.type));
  return a.count > kMaxRigValues ? kMaxRigValues + 1 : a.count * components;
}

Status checkRigSize(const tinygltf::Model& model, const tinygltf::Mesh& gmesh, Eigen::Index vertex_count,
                    const std::string& label) {
  std::size_t total = 0;
  auto add = [&](std::size_t n) { total = std::min(total + std::min(n, kMaxRigValues + 1), kMaxRigValues + 1); };
  const std::size_t targets = gmesh.primitives.front().targets.size();
  for (std::size_t t = 0; t < targets; ++t) add(static_cast<std::size_t>(vertex_count) * 6);  // positions, normals
  for (const tinygltf::Animation& animation : model.animations) {
    for (const tinygltf::AnimationChannel& channel : animation.channels) {
      if (channel.sampler < 0 || static_cast<std::size_t>(channel.sampler) >= animation.samplers.size()) continue;
      const tinygltf::AnimationSampler& sampler = animation.samplers[static_cast<std::size_t>(channel.sampler)];
      add(accessorValueCount(model, sampler.input));
      add(accessorValueCount(model, sampler.output));
    }
  }
  if (total > kMaxRigValues) {
    return makeError(ErrorCode::kUnsupported, label + ": the morph targets and animations would need more than " +
                                                  std::to_string(kMaxRigValues) + " values in memory");
  }
  return Ok{};
}

// One of the rig's other meshes (readOtherMeshes), read like the face.
Result<RigPart> readPart(const tinygltf::Model& model, const MeshChoice& choice, const Skin* face_skin,
                         const std::string& label, std::vector<std::string>& warnings) {
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  const std::string mesh_name = "mesh " + std::to_string(choice.mesh) + quoted(gmesh.name);
  const std::vector<PrimitiveRange> ranges = primitiveRanges(model, gmesh);
  if (auto ok = checkRigSize(model, gmesh, vertexTotal(ranges), label); !ok) return ok.error();
  LoadedMesh loaded;
  auto built = buildMesh(model, choice, label, std::move(loaded));
  if (!built) return built.error();
  for (std::string& warning : built->report.warnings) warnings.push_back(std::move(warning));
  Rig read;
  if (auto ok = readSkinning(model, choice, ranges, mesh_name, label, read, warnings, face_skin); !ok) return ok.error();
  if (auto ok = readMorphing(model, choice, ranges, mesh_name, label, read, warnings); !ok) return ok.error();
  auto attributes = readVertexAttributes(model, gmesh, ranges, mesh_name, label, warnings);
  if (!attributes) return attributes.error();
  RigPart part;
  part.name = gmesh.name.empty() ? "mesh_" + std::to_string(choice.mesh) : gmesh.name;
  part.mesh = std::move(built->mesh);
  part.node = choice.node;
  part.weights = std::move(read.weights);
  part.morph_targets = std::move(read.morph_targets);
  part.morph_default_weights = std::move(read.morph_default_weights);
  part.attributes = std::move(*attributes);
  part.triangle_materials = triangleMaterials(model, gmesh, part.mesh.triangleCount(), mesh_name, warnings);
  return part;
}

// Every node instancing a mesh other than the face's node, in node order, as
// a part. A part must share the face's skin (or both be unskinned) and have
// triangles; others are dropped with a warning naming them.
Status readOtherMeshes(const tinygltf::Model& model, const MeshChoice& face, const std::string& label, Rig& rig,
                       std::vector<std::string>& warnings) {
  const int face_skin = face.node >= 0 ? model.nodes[static_cast<std::size_t>(face.node)].skin : -1;
  for (std::size_t n = 0; n < model.nodes.size(); ++n) {
    const tinygltf::Node& node = model.nodes[n];
    if (node.mesh < 0 || static_cast<int>(n) == face.node) continue;
    if (static_cast<std::size_t>(node.mesh) >= model.meshes.size()) {
      return parseError(label, "node " + std::to_string(n) + " refers to mesh " + std::to_string(node.mesh) +
                                   " but the file has " + std::to_string(model.meshes.size()));
    }
    const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(node.mesh)];
    const std::string what = "mesh " + std::to_string(node.mesh) + quoted(gmesh.name) + " (node " + std::to_string(n) + ")";
    const bool skinned = node.skin >= 0 && face.skinned;
    if (node.skin >= 0 && node.skin != face_skin) {
      warnings.push_back(what + " is skinned to another skin than the face's; dropped");
      continue;
    }
    const bool triangles_only = std::all_of(gmesh.primitives.begin(), gmesh.primitives.end(), [](const tinygltf::Primitive& p) {
      return p.mode >= TINYGLTF_MODE_TRIANGLES && p.mode <= TINYGLTF_MODE_TRIANGLE_FAN;
    });
    if (gmesh.primitives.empty() || !triangles_only) {
      warnings.push_back(what + " is not a triangle mesh (points, lines); dropped");
      continue;
    }
    MeshChoice choice{node.mesh, static_cast<int>(n), skinned, what};
    auto part = readPart(model, choice, rig.skin ? &*rig.skin : nullptr, label, warnings);
    if (!part) return part.error();
    rig.parts.push_back(std::move(*part));
  }
  return Ok{};
}

// Everything beyond the mesh itself (buildMesh has read and placed that).
Status readRigData(const tinygltf::Model& model, const MeshChoice& choice, const std::string& label, Rig& rig,
                   std::vector<std::string>& warnings) {
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  const std::string mesh_name = "mesh " + std::to_string(choice.mesh);
  const std::vector<PrimitiveRange> ranges = primitiveRanges(model, gmesh);
  if (auto ok = checkRigSize(model, gmesh, vertexTotal(ranges), label); !ok) return ok.error();
  rig.mesh_name = gmesh.name;
  rig.mesh_node = choice.node;
  readMaterials(model, rig, warnings);
  rig.triangle_materials = triangleMaterials(model, gmesh, rig.mesh.triangleCount(), mesh_name, warnings);
  auto nodes = readNodes(model, label, warnings);
  if (!nodes) return nodes.error();
  rig.nodes = std::move(*nodes);
  if (auto ok = readSkinning(model, choice, ranges, mesh_name, label, rig, warnings); !ok) return ok.error();
  if (auto ok = readMorphing(model, choice, ranges, mesh_name, label, rig, warnings); !ok) return ok.error();
  if (auto ok = readOtherMeshes(model, choice, label, rig, warnings); !ok) return ok.error();
  std::map<int, int> morph_targets_of;
  if (choice.node >= 0) morph_targets_of[choice.node] = static_cast<int>(rig.morph_targets.size());
  for (const RigPart& part : rig.parts) morph_targets_of[part.node] = static_cast<int>(part.morph_targets.size());
  auto animations = readAnimations(model, morph_targets_of, label, warnings);
  if (!animations) return animations.error();
  rig.animations = std::move(*animations);
  auto attributes = readVertexAttributes(model, gmesh, ranges, mesh_name, label, warnings);
  if (!attributes) return attributes.error();
  rig.attributes = std::move(*attributes);
  return Ok{};
}

Result<LoadedRig> readRigImpl(Bytes bytes, const std::string& label, bool binary,
                              const std::optional<std::filesystem::path>& base_dir) {
  LoadedMesh loaded_mesh;
  auto parsed = parseGltf(bytes, label, binary, base_dir, loaded_mesh.report);
  if (!parsed) return parsed.error();
  auto mesh = chosenMesh(*parsed, label, std::move(loaded_mesh));
  if (!mesh) return mesh.error();
  LoadedRig loaded;
  loaded.rig.mesh = std::move(mesh->mesh);
  loaded.report = std::move(mesh->report);
  if (auto ok = readRigData(parsed->model, parsed->choice, label, loaded.rig, loaded.report.warnings); !ok) {
    return ok.error();
  }
  return loaded;
}

}  // namespace

}  // namespace core::gltf

namespace core {

Result<LoadedRig> readRigGltf(std::span<const std::uint8_t> bytes, const std::string& label, bool binary) {
  return gltf::readRigImpl(bytes, label, binary, std::nullopt);
}

// Like readMesh: .glb / .gltf by extension, else by the GLB magic; a .gltf may
// use buffer files in its own directory.
Result<LoadedRig> readRig(const std::filesystem::path& path) {
  auto file = MappedFile::open(path);
  if (!file) return file.error();
  const std::span<const std::uint8_t> bytes = file->bytes();
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const bool magic = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  const bool binary = ext == ".glb" || (ext != ".gltf" && magic);
  return gltf::readRigImpl(bytes, path.filename().string(), binary, path.parent_path());
}

}  // namespace core
