// Beyond the thesis: a detection that the scan shows by one flat face, placed along that face.
#pragma once

#include "subgroup_matcher.hpp"

#include <binpose/detector.hpp>

#include <vector>

namespace binpose {

/// Each detection whose support lies on one plane (Matcher::faceOf) moved along that plane, in
/// shrinking steps, while its score grows; its score is then the moved pose's. In parallel, each
/// its own, so the result is the same whatever the threads.
void slideAlongFaces(std::vector<Detection>& detections, const Matcher& m);

}  // namespace binpose
