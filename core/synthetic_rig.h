// A procedural facial rig on a synthetic head, so the demo and the default
// tests need no outside data: skeleton root > neck > head > {jaw, eye_L,
// eye_R}; smooth skin weights; shapes jawOpen, mouthSmile_L/R, browInnerUp,
// eyeBlink_L/R; a 2-second clip (jaw open, head turn, shape pulses); a REGION
// label per vertex (0 skin, 1 upper lip, 2 lower lip, 3 upper lids, 4 lower lids).
#pragma once

#include "core/rig.h"
#include "core/synthetic_head.h"

namespace core {

struct SyntheticRig {
  Rig rig;
  LandmarkSet landmarks;
};

// The head is generated with a slightly open mouth so the lips are separate
// sheets (jawOpen can part them).
SyntheticRig generateRig(const HeadShape& shape = {}, const HeadResolution& resolution = {});

enum RegionLabel { kRegionSkin = 0, kRegionUpperLip = 1, kRegionLowerLip = 2, kRegionUpperLid = 3, kRegionLowerLid = 4 };

}  // namespace core
