// A procedural facial rig on a synthetic head, so the demo and the default
// tests need no outside data: skeleton root > neck > head > {jaw, eye_L,
// eye_R}; smooth skin weights; shapes jawOpen, mouthSmile_L/R, browInnerUp,
// eyeBlink_L/R; a 2-second clip (jaw open, head turn, shape pulses); the
// head's region labels (RegionLabel) as its REGION label attribute.
#pragma once

#include "core/rig/rig.h"
#include "core/synthetic/synthetic_head.h"

namespace core {

struct SyntheticRig {
  Rig rig;
  LandmarkSet landmarks;
};

// The head is generated with a slightly open mouth so the lips are separate
// sheets (jawOpen can part them).
SyntheticRig generateRig(const HeadShape& shape = {}, const HeadResolution& resolution = {});

}  // namespace core
