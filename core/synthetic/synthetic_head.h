// Procedural head-like meshes with anatomically placed landmarks, so the demo
// and the default tests need no outside data. A head is an ellipsoid shell open
// at the back and the neck, with nose, brows, cheeks, lips and chin as smooth
// bumps, eye holes and an optional open mouth slit (like scanned/sculpted faces
// with their openings). Coordinates follow glTF: metres, +Y up, face toward +Z,
// +X = subject's left.
#pragma once

#include "core/io/landmarks.h"
#include "core/geometry/mesh.h"

namespace core {

// Proportions; angles are ellipsoid longitude (theta, 0 = front, + = subject's
// left) and latitude (phi, + = up) in radians.
struct HeadShape {
  double width = 0.075;        // x semi-axis, metres
  double height = 0.11;        // y semi-axis, metres
  double depth = 0.095;        // z semi-axis, metres
  double jaw_width = 1.0;      // x scale of the lower face (below the mouth), 1 = none
  double nose_length = 0.022;  // how far the nose tip stands out, metres
  double nose_width = 0.09;    // nose half-width (theta)
  double eye_spacing = 0.33;   // eye centre longitude (theta)
  double eye_height = 0.14;    // eye centre latitude (phi)
  double mouth_height = -0.26; // mouth line latitude (phi)
  double mouth_width = 0.2;    // mouth half-width (theta)
  double mouth_open = 0.0;     // half-height of the mouth slit (phi); 0 = closed lips, no hole
  double brow = 0.008;         // brow ridge height, metres
  double cheek = 0.008;        // cheekbone height, metres
  double lip = 0.005;          // lip fullness, metres
  double chin = 0.01;          // chin prominence, metres
};

struct HeadResolution {
  int columns = 96;            // grid cells around (theta)
  int rows = 72;               // grid cells up (phi)
  bool alternate_diagonals = false;  // flip every other cell's diagonal (other triangulation)
  double jitter = 0.0;         // random in-surface vertex offset, fraction of a cell (other sampling)
  unsigned seed = 0;           // for jitter
};

// Region labels of a generated head (Mesh::regions, written as _REGION).
enum RegionLabel { kRegionSkin = 0, kRegionUpperLip = 1, kRegionLowerLip = 2, kRegionUpperLid = 3, kRegionLowerLid = 4 };

struct SyntheticHead {
  Mesh mesh;                   // regions: lips and lids labelled (RegionLabel), as a TD would paint them
  LandmarkSet landmarks;       // 68 iBUG-named landmarks as face + barycentric
};

SyntheticHead generateHead(const HeadShape& shape = {}, const HeadResolution& resolution = {});

// A plausible random identity: every proportion varied by up to +-`variation`
// (relative), deterministic in `seed`.
HeadShape randomHeadShape(unsigned seed, double variation = 0.15);

}  // namespace core
