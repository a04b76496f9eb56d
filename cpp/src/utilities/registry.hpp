// The utilities by name: one line each. evaluate_views looks the name up here.
#pragma once

#include "average_entropy.hpp"
#include "four_term.hpp"
#include "ig.hpp"
#include "surface.hpp"
#include "visibility.hpp"

// X(name, policy, weigh by distance?)
#define NBV_UTILITIES(X)                         \
  X("ig", InformationGain, false)                \
  X("ig_distance", InformationGain, true)        \
  X("occlusion_aware", OcclusionAware, false)    \
  X("unobserved_voxel", UnobservedVoxel, false)  \
  X("rear_side_voxel", RearSideVoxel, false)     \
  X("rear_side_entropy", RearSideEntropy, false) \
  X("proximity_count", ProximityCount, false)    \
  X("average_entropy", AverageEntropy, false)    \
  X("four_term", FourTerm, true)                 \
  X("surface", Surface, false)
