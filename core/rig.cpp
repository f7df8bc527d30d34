#include "core/rig.h"

#include <functional>

namespace core {

std::vector<Eigen::Matrix4d> nodeWorldTransforms(const std::vector<Node>& nodes) {
  const std::size_t n = nodes.size();
  std::vector<Eigen::Matrix4d> world(n);
  std::vector<char> done(n, 0);
  // Iterative by depth: a parent is resolved before its children; cycles (an
  // invalid file) fall back to treating the node as a root.
  std::function<const Eigen::Matrix4d&(std::size_t, int)> resolve = [&](std::size_t i, int depth) -> const Eigen::Matrix4d& {
    if (done[i]) return world[i];
    Eigen::Affine3d local = Eigen::Affine3d::Identity();
    local.translate(nodes[i].translation);
    local.rotate(nodes[i].rotation.normalized());
    local.scale(nodes[i].scale);
    const int p = nodes[i].parent;
    if (p >= 0 && static_cast<std::size_t>(p) < n && depth < static_cast<int>(n)) {
      world[i] = resolve(static_cast<std::size_t>(p), depth + 1) * local.matrix();
    } else {
      world[i] = local.matrix();
    }
    done[i] = 1;
    return world[i];
  };
  for (std::size_t i = 0; i < n; ++i) resolve(i, 0);
  return world;
}

}  // namespace core
