#pragma once
// Beyond the thesis: a weak detection tried again from poses turned a little (on a noisy scan),
// and from the part turned over.
#include "model_shape.hpp"
#include "subgroup_matcher.hpp"

#include <binpose/detector.hpp>

#include <vector>

namespace binpose {

/// Each hypothesis scoring under a weak score is refined again (ICP, 5.2.6) from its pose turned
/// by a few degrees about each of the part's axes through its centroid, and takes the best of
/// those poses where it scores clearly more, stands (Matcher::stands) and has not moved off its
/// place. Each scoring under a higher score is then tried the same way from its pose turned by
/// the part's near-symmetric half turns, `flips` (nearFlips), held near the turned start's place
/// instead, and when it takes one, turned a little again. On a `quiet` scan (one not polished)
/// the weak hypotheses are only tried turned over, `flips` being those of withFaceFlips. In
/// parallel, each its own: the result is the same whatever the threads.
void reseatWeak(std::vector<Hypothesis>& hypotheses, const Matcher& matcher, const ModelShape& shape,
                const std::vector<Pose>& flips, bool quiet);

}  // namespace binpose
