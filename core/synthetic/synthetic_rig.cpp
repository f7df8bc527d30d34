#include "core/synthetic/synthetic_rig.h"

#include <cmath>
#include <numbers>

namespace core {

namespace {

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

Node joint(const std::string& name, int parent, const Eigen::Vector3d& t) {
  Node n;
  n.name = name;
  n.parent = parent;
  n.translation = t;
  return n;
}

}  // namespace

SyntheticRig generateRig(const HeadShape& input_shape, const HeadResolution& resolution) {
  HeadShape shape = input_shape;
  if (shape.mouth_open <= 0.0) shape.mouth_open = 0.012;
  SyntheticHead head = generateHead(shape, resolution);
  SyntheticRig out;
  out.landmarks = head.landmarks;
  Rig& rig = out.rig;
  rig.mesh = head.mesh;
  rig.mesh_name = "face";
  const Eigen::MatrixX3d& p = rig.mesh.positions;
  const Eigen::Index nv = p.rows();

  auto lm = [&](const std::string& name) {
    const Landmark& l = head.landmarks.landmarks[static_cast<std::size_t>(head.landmarks.indexOf(name))];
    return Eigen::Vector3d(interpolateOnFace(p, rig.mesh.triangles, l.face, l.barycentric).transpose());
  };
  const Eigen::Vector3d mouth_left = lm("mouth_outer_6"), mouth_right = lm("mouth_outer_0");
  const Eigen::Vector3d mouth_centre = 0.5 * (lm("mouth_inner_2") + lm("mouth_inner_6"));
  const Eigen::Vector3d chin = lm("jaw_08");
  const Eigen::Vector3d eye_l = 0.5 * (lm("eye_left_0") + lm("eye_left_3"));
  const Eigen::Vector3d eye_r = 0.5 * (lm("eye_right_0") + lm("eye_right_3"));
  const double height = p.col(1).maxCoeff() - p.col(1).minCoeff();
  const double ymin = p.col(1).minCoeff();

  // Skeleton (world positions; identity rotations, so local = differences).
  const Eigen::Vector3d root_w(0, ymin + 0.05 * height, -0.1 * shape.depth);
  const Eigen::Vector3d neck_w(0, ymin + 0.25 * height, -0.2 * shape.depth);
  const Eigen::Vector3d head_w(0, eye_l.y() - 0.1 * height, -0.25 * shape.depth);
  const Eigen::Vector3d jaw_w(0, mouth_centre.y() + 0.08 * height, -0.35 * shape.depth);
  const Eigen::Vector3d eye_l_w = eye_l - Eigen::Vector3d(0, 0, 0.15 * shape.depth);
  const Eigen::Vector3d eye_r_w = eye_r - Eigen::Vector3d(0, 0, 0.15 * shape.depth);
  rig.nodes = {joint("root", -1, root_w), joint("neck", 0, neck_w - root_w), joint("head", 1, head_w - neck_w),
               joint("jaw", 2, jaw_w - head_w), joint("eye_L", 2, eye_l_w - head_w), joint("eye_R", 2, eye_r_w - head_w)};
  Node mesh_node;
  mesh_node.name = "face";
  rig.nodes.push_back(mesh_node);
  rig.mesh_node = 6;
  Skin skin;
  skin.name = "face_skin";
  skin.joints = {0, 1, 2, 3, 4, 5};
  const std::vector<Eigen::Matrix4d> world = nodeWorldTransforms(rig.nodes);
  for (int j : skin.joints) skin.inverse_bind.push_back(world[static_cast<std::size_t>(j)].inverse());
  skin.skeleton = 0;
  rig.skin = skin;

  const double lip_band = 0.25 * (mouth_left - mouth_right).norm();
  const Eigen::VectorXi& region = rig.mesh.regions;  // lips and lids (generateHead)
  rig.attributes.labels[kRegionAttribute] = region;

  // Weights: jaw below the mouth line (fading toward the ears), head above,
  // neck and root from height falloffs.
  std::vector<Eigen::Triplet<double>> w;
  for (Eigen::Index v = 0; v < nv; ++v) {
    const Eigen::Vector3d x = p.row(v).transpose();
    // Lower face in front of the ears, fading out below the chin.
    double jaw = (1.0 - smoothstep(mouth_centre.y() - 0.3 * lip_band, mouth_centre.y() + 0.3 * lip_band, x.y())) *
                 smoothstep(chin.y() - 0.15 * height, chin.y(), x.y()) *
                 smoothstep(-0.2 * shape.depth, 0.4 * shape.depth, x.z());
    if (region(v) == kRegionLowerLip) jaw = 1.0;
    if (region(v) == kRegionUpperLip) jaw = 0.0;
    const double neck = 1.0 - smoothstep(neck_w.y(), head_w.y() - 0.05 * height, x.y());
    const double root = 1.0 - smoothstep(root_w.y(), neck_w.y(), x.y());
    double rest = 1.0 - jaw;
    const double r = rest * root, n = rest * (neck - root) * (neck > root ? 1 : 0), h = rest - r - n;
    const double parts[4] = {r, n, h, jaw};
    for (int j = 0; j < 4; ++j) if (parts[j] > 1e-4) w.emplace_back(static_cast<int>(v), j, parts[j]);
  }
  rig.weights.resize(nv, 6);
  rig.weights.setFromTriplets(w.begin(), w.end());
  for (Eigen::Index v = 0; v < nv; ++v) {
    const double s = rig.weights.row(v).sum();
    if (s > 0) rig.weights.row(v) /= s;
  }
  rig.weights.makeCompressed();

  // Shapes.
  auto shapeOf = [&](const std::string& name, auto&& delta) {
    MorphTarget t;
    t.name = name;
    t.position_deltas = Eigen::MatrixX3d::Zero(nv, 3);
    for (Eigen::Index v = 0; v < nv; ++v) t.position_deltas.row(v) = delta(Eigen::Vector3d(p.row(v).transpose()), v).transpose();
    rig.morph_targets.push_back(std::move(t));
  };
  const double open_angle = 15.0 * std::numbers::pi / 180.0;
  shapeOf("jawOpen", [&](const Eigen::Vector3d& x, Eigen::Index v) -> Eigen::Vector3d {
    double jw = 0;
    for (SkinWeights::InnerIterator it(rig.weights, v); it; ++it) if (it.col() == 3) jw = it.value();
    const Eigen::Vector3d d = x - jaw_w;
    return jw * (Eigen::AngleAxisd(open_angle, Eigen::Vector3d::UnitX()) * d - d);
  });
  for (int side : {1, -1}) {
    const Eigen::Vector3d corner = side > 0 ? mouth_left : mouth_right;
    shapeOf(side > 0 ? "mouthSmile_L" : "mouthSmile_R", [&](const Eigen::Vector3d& x, Eigen::Index) -> Eigen::Vector3d {
      const double f = std::exp(-(x - corner).squaredNorm() / (2 * lip_band * lip_band));
      return f * Eigen::Vector3d(side * 0.3 * lip_band, 0.35 * lip_band, -0.1 * lip_band);
    });
  }
  const Eigen::Vector3d brow = 0.5 * (lm("brow_left_0") + lm("brow_right_4"));
  shapeOf("browInnerUp", [&](const Eigen::Vector3d& x, Eigen::Index) -> Eigen::Vector3d {
    const double f = std::exp(-(x - brow).squaredNorm() / (2 * std::pow(1.5 * lip_band, 2)));
    return f * Eigen::Vector3d(0, 0.4 * lip_band, 0);
  });
  for (int side : {1, -1}) {
    const Eigen::Vector3d eye = side > 0 ? eye_l : eye_r;
    shapeOf(side > 0 ? "eyeBlink_L" : "eyeBlink_R", [&](const Eigen::Vector3d& x, Eigen::Index v) -> Eigen::Vector3d {
      if (region(v) != kRegionUpperLid || (x.x() - eye.x()) * side < -0.03) return Eigen::Vector3d::Zero();
      const double f = 1.0 - smoothstep(0.0, 0.03, std::abs(x.x() - eye.x()));
      return f * Eigen::Vector3d(0, -0.012, 0.002);
    });
  }
  rig.morph_default_weights = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(rig.morph_targets.size()));

  // One clip: 2 s at 30 fps, jaw opens and closes, head turns, shapes pulse.
  Animation clip;
  clip.name = "talk";
  const int keys = 61;
  AnimationChannel jaw_rot, head_rot, weights;
  jaw_rot.node = 3;
  jaw_rot.path = AnimationPath::kRotation;
  head_rot.node = 2;
  head_rot.path = AnimationPath::kRotation;
  weights.node = rig.mesh_node;
  weights.path = AnimationPath::kWeights;
  AnimationChannel jaw_move;
  jaw_move.node = 3;
  jaw_move.path = AnimationPath::kTranslation;
  for (AnimationChannel* c : {&jaw_rot, &head_rot, &weights, &jaw_move}) c->times.resize(keys);
  jaw_rot.values.resize(keys, 4);
  head_rot.values.resize(keys, 4);
  jaw_move.values.resize(keys, 3);
  weights.values = Eigen::MatrixXd::Zero(keys, static_cast<Eigen::Index>(rig.morph_targets.size()));
  for (int k = 0; k < keys; ++k) {
    const double t = k / 30.0;
    for (AnimationChannel* c : {&jaw_rot, &head_rot, &weights, &jaw_move}) c->times(k) = t;
    const double open = std::sin(std::numbers::pi * std::min(t, 1.0));
    const Eigen::Quaterniond qj(Eigen::AngleAxisd(open * 18.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX()));
    const Eigen::Quaterniond qh(Eigen::AngleAxisd(0.4 * std::sin(std::numbers::pi * t), Eigen::Vector3d::UnitY()));
    jaw_rot.values.row(k) << qj.x(), qj.y(), qj.z(), qj.w();
    head_rot.values.row(k) << qh.x(), qh.y(), qh.z(), qh.w();
    jaw_move.values.row(k) = (rig.nodes[3].translation + Eigen::Vector3d(0, 0, 0.004 * open)).transpose();
    for (Eigen::Index s = 0; s < weights.values.cols(); ++s) {
      weights.values(k, s) = std::exp(-std::pow((t - 0.3 - 0.25 * static_cast<double>(s)) / 0.15, 2));
    }
  }
  clip.channels = {jaw_rot, jaw_move, head_rot, weights};
  rig.animations.push_back(std::move(clip));
  return out;
}

}  // namespace core
