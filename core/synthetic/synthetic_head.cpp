#include "core/synthetic/synthetic_head.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <array>
#include <string>
#include <vector>

namespace core {

namespace {

constexpr double kThetaMax = 2.4;                  // open at the back of the head
constexpr double kPhiMin = -0.95, kPhiMax = 1.2;   // neck cut to crown
constexpr double kPhiCentre = -0.05;               // densest row: mid-face
constexpr double kDensity = 2.0;                   // cells are (1 + kDensity) x finer mid-face than at the edge

// Grid coordinate s in [-1, 1] -> angle, denser near s = 0 (the face) so a
// modest vertex budget resolves lips, lids and nostrils.
double gridMap(double s) { return (s + kDensity * s * s * s) / (1.0 + kDensity); }
double thetaAt(double s) { return kThetaMax * gridMap(s); }
double phiAt(double s) { return kPhiCentre + (s < 0 ? kPhiCentre - kPhiMin : kPhiMax - kPhiCentre) * gridMap(s); }
// Inverse of the monotone map by bisection.
template <typename F>
double inverseMap(F f, double value) {
  double lo = -1.0, hi = 1.0;
  for (int k = 0; k < 60; ++k) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) < value ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Closest point of q to 2D triangle (a, b, c), as barycentrics.
Eigen::Vector3d closestBarycentric2d(const Eigen::Vector2d& q, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                     const Eigen::Vector2d& c) {
  Eigen::Matrix2d m;
  m << b - a, c - a;
  const Eigen::Vector2d uv = m.colPivHouseholderQr().solve(q - a);
  const Eigen::Vector3d bary(1 - uv(0) - uv(1), uv(0), uv(1));
  if (bary.minCoeff() >= 0.0) return bary;
  // Outside: the nearest point on one of the three edges.
  const Eigen::Vector2d corners[3] = {a, b, c};
  Eigen::Vector3d best = Eigen::Vector3d(1, 0, 0);
  double best_d = std::numeric_limits<double>::infinity();
  for (int e = 0; e < 3; ++e) {
    const Eigen::Vector2d p0 = corners[e], p1 = corners[(e + 1) % 3];
    const double len2 = (p1 - p0).squaredNorm();
    const double t = len2 > 0 ? std::clamp((q - p0).dot(p1 - p0) / len2, 0.0, 1.0) : 0.0;
    const double d = (p0 + t * (p1 - p0) - q).squaredNorm();
    if (d < best_d) {
      best_d = d;
      best.setZero();
      best(e) = 1 - t;
      best((e + 1) % 3) = t;
    }
  }
  return best;
}

double gauss(double t, double p, double t0, double p0, double st, double sp) {
  const double a = (t - t0) / st, b = (p - p0) / sp;
  return std::exp(-0.5 * (a * a + b * b));
}

// Surface point of the head at (theta, phi).
Eigen::Vector3d headPoint(const HeadShape& s, double t, double p) {
  const double jaw = p < s.mouth_height ? 1.0 + (s.jaw_width - 1.0) * std::min(1.0, (s.mouth_height - p) / 0.3) : 1.0;
  const Eigen::Vector3d e(s.width * jaw * std::sin(t) * std::cos(p), s.height * std::sin(p),
                          s.depth * std::cos(t) * std::cos(p));
  Eigen::Vector3d n(e.x() / (s.width * s.width), e.y() / (s.height * s.height), e.z() / (s.depth * s.depth));
  n.normalize();
  const double nose_top = s.eye_height + 0.02, nose_tip = s.mouth_height + 0.17;
  double h = 0.0;
  // Nose: a ridge from the bridge to the tip, growing toward the tip.
  if (p < nose_top + 0.1 && p > nose_tip - 0.12) {
    const double along = std::clamp((nose_top - p) / (nose_top - nose_tip), 0.0, 1.0);
    const double fall = p < nose_tip ? std::exp(-0.5 * std::pow((p - nose_tip) / 0.03, 2)) : 1.0;
    const double rise = p > nose_top ? std::exp(-0.5 * std::pow((p - nose_top) / 0.04, 2)) : 1.0;
    const double width = s.nose_width * (0.45 + 0.55 * along);
    h += s.nose_length * (0.15 + 0.85 * along * along) * fall * rise * std::exp(-0.5 * std::pow(t / width, 2));
  }
  for (double side : {-1.0, 1.0}) {
    h -= 0.35 * s.brow * gauss(t, p, side * s.eye_spacing, s.eye_height, 0.12, 0.06);            // eye socket
    h += s.brow * gauss(t, p, side * s.eye_spacing, s.eye_height + 0.12, 0.2, 0.035);          // brow ridge
    h += s.cheek * gauss(t, p, side * (s.eye_spacing + 0.15), s.eye_height - 0.17, 0.16, 0.08); // cheekbone
  }
  h += s.lip * gauss(t, p, 0.0, s.mouth_height + 0.035, s.mouth_width * 0.7, 0.03);  // upper lip
  h += s.lip * gauss(t, p, 0.0, s.mouth_height - 0.04, s.mouth_width * 0.6, 0.035);  // lower lip
  h += s.chin * gauss(t, p, 0.0, s.mouth_height - 0.22, 0.2, 0.08);                   // chin
  return e + h * n;
}

struct ParamPoint {
  const char* prefix;
  int index;
  double theta, phi;
};

// 68 landmarks in iBUG order and naming (as in the landmarks of DESIGN.md).
std::vector<ParamPoint> landmarkParams(const HeadShape& s) {
  std::vector<ParamPoint> out;
  const double es = s.eye_spacing, eh = s.eye_height, mh = s.mouth_height, mw = s.mouth_width;
  for (int i = 0; i <= 16; ++i) {  // jaw: subject's right ear (-X) round the chin to the left ear
    const double a = -std::numbers::pi / 2 + std::numbers::pi * i / 16.0;
    out.push_back({"jaw_", i, 1.15 * std::sin(a), mh - 0.02 - 0.36 * std::cos(a) + 0.12 * (1 - std::cos(a)) * 0.0});
  }
  for (int i = 0; i < 5; ++i) out.push_back({"brow_right_", i, -(es + 0.2) + 0.1 * i, eh + 0.13 + 0.02 * std::sin(std::numbers::pi * i / 4)});
  for (int i = 0; i < 5; ++i) out.push_back({"brow_left_", i, (es - 0.2) + 0.1 * i, eh + 0.13 + 0.02 * std::sin(std::numbers::pi * i / 4)});
  const double nose_top = eh + 0.02, nose_tip = mh + 0.17;
  for (int i = 0; i < 4; ++i) out.push_back({"nose_bridge_", i, 0.0, nose_top - (nose_top - nose_tip) * i / 3.0});
  for (int i = 0; i < 5; ++i) {
    out.push_back({"nose_base_", i, s.nose_width * 0.9 * (i - 2) / 2.0, nose_tip - 0.05 + 0.012 * std::abs(i - 2)});
  }
  // Eyes: 0 and 3 are the corners, 1-2 the upper lid, 4-5 the lower lid, just
  // outside the eye hole so they lie on the surface.
  const double ew = 0.125, eh_lid = 0.055;
  for (double side : {-1.0, 1.0}) {
    const char* prefix = side < 0 ? "eye_right_" : "eye_left_";
    const double angles[6] = {std::numbers::pi, 2 * std::numbers::pi / 3, std::numbers::pi / 3, 0.0, -std::numbers::pi / 3, -2 * std::numbers::pi / 3};
    for (int i = 0; i < 6; ++i) {
      // eye_right runs outer -> inner corner, eye_left inner -> outer (image order).
      const double a = side < 0 ? angles[i] : std::numbers::pi - angles[i];
      out.push_back({prefix, i, side * es + ew * std::cos(a), eh + eh_lid * std::sin(a)});
    }
  }
  const double open = std::max(s.mouth_open, 0.0);
  for (int i = 0; i < 12; ++i) {  // outer lip line from the right corner, over the top
    const double a = std::numbers::pi - 2 * std::numbers::pi * i / 12.0;
    out.push_back({"mouth_outer_", i, (mw + 0.02) * std::cos(a), mh + (0.055 + open) * std::sin(a)});
  }
  for (int i = 0; i < 8; ++i) {  // inner lip line, at the lips' contact (or the slit's edge)
    const double a = std::numbers::pi - 2 * std::numbers::pi * i / 8.0;
    out.push_back({"mouth_inner_", i, (mw - 0.03) * std::cos(a), mh + (open + 0.012) * std::sin(a)});
  }
  return out;
}

bool inEyeHole(const HeadShape& s, double t, double p) {
  for (double side : {-1.0, 1.0}) {
    const double a = (t - side * s.eye_spacing) / 0.1, b = (p - s.eye_height) / 0.035;
    if (a * a + b * b < 1.0) return true;
  }
  return false;
}

bool inMouthHole(const HeadShape& s, double t, double p) {
  if (s.mouth_open <= 0.0) return false;
  const double a = t / (s.mouth_width - 0.04), b = (p - s.mouth_height) / s.mouth_open;
  return a * a + b * b < 1.0;
}

}  // namespace

namespace {

// Lips by the mouth line (a band around it, split above / below), lids by
// the eye holes, from the landmarks: what a TD would paint.
Eigen::VectorXi lipAndLidRegions(const Mesh& mesh, const LandmarkSet& landmarks, const HeadShape& shape) {
  auto at = [&](const std::string& name) {
    const Landmark& l = landmarks.landmarks[static_cast<std::size_t>(landmarks.indexOf(name))];
    return Eigen::Vector3d(interpolateOnFace(mesh.positions, mesh.triangles, l.face, l.barycentric).transpose());
  };
  const Eigen::Vector3d mouth_left = at("mouth_outer_6"), mouth_right = at("mouth_outer_0");
  const Eigen::Vector3d mouth_centre = 0.5 * (at("mouth_inner_2") + at("mouth_inner_6"));
  const Eigen::Vector3d eye_l = 0.5 * (at("eye_left_0") + at("eye_left_3"));
  const Eigen::Vector3d eye_r = 0.5 * (at("eye_right_0") + at("eye_right_3"));
  const double lip_band = 0.25 * (mouth_left - mouth_right).norm();
  const double mouth_half_width = 0.55 * (mouth_left - mouth_right).norm();
  Eigen::VectorXi region = Eigen::VectorXi::Constant(mesh.vertexCount(), kRegionSkin);
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) {
    const Eigen::Vector3d x = mesh.positions.row(v).transpose();
    const double dx = std::abs(x.x() - mouth_centre.x()), dy = x.y() - mouth_centre.y();
    if (x.z() > mouth_centre.z() - 0.3 * lip_band && dx < mouth_half_width && std::abs(dy) < lip_band) {
      region(v) = dy > 0 ? kRegionUpperLip : kRegionLowerLip;
    }
    for (const Eigen::Vector3d& e : {eye_l, eye_r}) {
      const double ex = std::abs(x.x() - e.x()), ey = x.y() - e.y();
      if (ex < 0.028 / 0.075 * shape.width && std::abs(ey) < 0.012 && x.z() > e.z() - 0.01) {
        region(v) = ey > 0 ? kRegionUpperLid : kRegionLowerLid;
      }
    }
  }
  return region;
}

}  // namespace

SyntheticHead generateHead(const HeadShape& shape, const HeadResolution& res) {
  const int nu = std::max(4, res.columns), nv = std::max(4, res.rows);
  std::mt19937 rng(res.seed);
  std::uniform_real_distribution<double> jitter(-res.jitter, res.jitter);

  // Grid in parameter space; interior vertices optionally jittered.
  Eigen::MatrixX2d param((nu + 1) * (nv + 1), 2);
  for (int j = 0; j <= nv; ++j) {
    for (int i = 0; i <= nu; ++i) {
      double si = -1.0 + 2.0 * i / nu, sj = -1.0 + 2.0 * j / nv;
      if (res.jitter > 0 && i > 0 && i < nu && j > 0 && j < nv) {
        si += jitter(rng) * 2.0 / nu;
        sj += jitter(rng) * 2.0 / nv;
      }
      param.row(j * (nu + 1) + i) << thetaAt(si), phiAt(sj);
    }
  }
  auto vid = [nu](int i, int j) { return j * (nu + 1) + i; };

  // Two triangles per cell (counter-clockwise seen from outside), dropping the
  // cells inside the eye holes and the mouth slit.
  std::vector<Eigen::Vector3i> tris;
  std::vector<std::array<int, 2>> cell_of;  // (cell, half) for landmark lookup
  std::vector<int> tri_of_cell(static_cast<std::size_t>(2 * nu * nv), -1);
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const double tc = thetaAt(-1.0 + (2.0 * i + 1.0) / nu), pc = phiAt(-1.0 + (2.0 * j + 1.0) / nv);
      if (inEyeHole(shape, tc, pc) || inMouthHole(shape, tc, pc)) continue;
      const int a = vid(i, j), b = vid(i + 1, j), c = vid(i + 1, j + 1), d = vid(i, j + 1);
      const bool flip = res.alternate_diagonals && ((i + j) % 2 == 1);
      const int cell = j * nu + i;
      if (!flip) {
        tri_of_cell[static_cast<std::size_t>(2 * cell)] = static_cast<int>(tris.size());
        tris.emplace_back(a, b, c);
        tri_of_cell[static_cast<std::size_t>(2 * cell + 1)] = static_cast<int>(tris.size());
        tris.emplace_back(a, c, d);
      } else {
        tri_of_cell[static_cast<std::size_t>(2 * cell)] = static_cast<int>(tris.size());
        tris.emplace_back(a, b, d);
        tri_of_cell[static_cast<std::size_t>(2 * cell + 1)] = static_cast<int>(tris.size());
        tris.emplace_back(b, c, d);
      }
    }
  }

  // Keep only vertices used by a triangle, in grid order.
  std::vector<int> remap(static_cast<std::size_t>(param.rows()), -1);
  for (const auto& t : tris) for (int k = 0; k < 3; ++k) remap[static_cast<std::size_t>(t(k))] = 0;
  int nvert = 0;
  for (auto& r : remap) if (r == 0) r = nvert++;

  SyntheticHead head;
  head.mesh.positions.resize(nvert, 3);
  for (Eigen::Index v = 0; v < param.rows(); ++v) {
    if (remap[static_cast<std::size_t>(v)] >= 0) {
      head.mesh.positions.row(remap[static_cast<std::size_t>(v)]) = headPoint(shape, param(v, 0), param(v, 1)).transpose();
    }
  }
  head.mesh.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t f = 0; f < tris.size(); ++f) {
    for (int k = 0; k < 3; ++k) head.mesh.triangles(static_cast<Eigen::Index>(f), k) = remap[static_cast<std::size_t>(tris[f](k))];
  }
  head.mesh.normals = computeVertexNormals(head.mesh.positions, head.mesh.triangles);

  // Landmarks: the triangle containing the parameter point, with barycentrics
  // from parameter space (exactly on the mesh).
  for (const ParamPoint& lp : landmarkParams(shape)) {
    const int ci = static_cast<int>((inverseMap(thetaAt, lp.theta) + 1.0) * 0.5 * nu);
    const int cj = static_cast<int>((inverseMap(phiAt, lp.phi) + 1.0) * 0.5 * nv);
    Landmark lm;
    lm.name = std::string(lp.prefix) + (std::string(lp.prefix) == "jaw_" && lp.index < 10 ? "0" : "") + std::to_string(lp.index);
    lm.kind = LandmarkKind::kFace;
    // Nearest kept triangle around the expected cell (in parameter space): a
    // landmark whose cell fell into a hole lands on the hole's rim.
    const Eigen::Vector2d q(lp.theta, lp.phi);
    double best = std::numeric_limits<double>::infinity();
    for (int j = std::max(0, cj - 4); j <= std::min(nv - 1, cj + 4); ++j) {
      for (int i = std::max(0, ci - 4); i <= std::min(nu - 1, ci + 4); ++i) {
        for (int half = 0; half < 2; ++half) {
          const int f = tri_of_cell[static_cast<std::size_t>(2 * (j * nu + i) + half)];
          if (f < 0) continue;
          const Eigen::Vector3i t = tris[static_cast<std::size_t>(f)];
          const Eigen::Vector2d a = param.row(t(0)), b = param.row(t(1)), c = param.row(t(2));
          const Eigen::Vector3d bary = closestBarycentric2d(q, a, b, c);
          const double d = (bary(0) * a + bary(1) * b + bary(2) * c - q).squaredNorm();
          if (d < best) {
            best = d;
            lm.face = f;
            lm.barycentric = bary;
          }
        }
      }
    }
    assert(lm.face >= 0);  // landmarkParams keeps every landmark near the surface
    head.landmarks.landmarks.push_back(lm);
  }
  head.mesh.regions = lipAndLidRegions(head.mesh, head.landmarks, shape);
  return head;
}

HeadShape randomHeadShape(unsigned seed, double variation) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-variation, variation);
  HeadShape s;
  s.width *= 1 + u(rng);
  s.height *= 1 + u(rng);
  s.depth *= 1 + u(rng);
  s.jaw_width *= 1 + u(rng);
  s.nose_length *= 1 + 2 * u(rng);
  s.nose_width *= 1 + u(rng);
  s.eye_spacing *= 1 + 0.5 * u(rng);
  s.eye_height *= 1 + 0.5 * u(rng);
  s.mouth_height *= 1 + 0.3 * u(rng);
  s.mouth_width *= 1 + 0.5 * u(rng);
  s.brow *= 1 + 2 * u(rng);
  s.cheek *= 1 + 2 * u(rng);
  s.lip *= 1 + 2 * u(rng);
  s.chin *= 1 + 2 * u(rng);
  return s;
}

}  // namespace core
