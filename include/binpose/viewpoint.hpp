#pragma once
// Where the sensor was, for a scan whose file does not say: an unorganized PLY exported in a
// robot's or a work cell's frame, whose origin may lie below the floor or inside the bin.
#include <binpose/types.hpp>

namespace binpose {

struct ViewpointGuess {
  Vec3 viewpoint = Vec3::Zero();  ///< the sensor origin to use, mm (the assumed one when kept)
  bool moved = false;             ///< whether the assumed origin was replaced
  /// Share of the scan's points the chosen viewpoint cannot see: behind it, or clearly behind
  /// another point on the same line of sight. A single-view scan shows its sensor only the first
  /// surface on each line of sight, so near 0 for the true viewpoint.
  float hidden = 0;
  float assumed_hidden = 0;  ///< the same share for the assumed origin
};

/// The hidden shares are measured on an even sample of at most 20 000 of the points.
/// Keeps `assumed` when it sees the scan as a sensor would (at most a few per cent hidden);
/// otherwise the viewpoint one scan extent away from the scan's centre, in the direction that
/// hides the fewest points: the best principal axis of the scan, then tilted while that hides
/// fewer; always with z >= 0 (a frame that is not the sensor's is a world frame, z up, the
/// sensor above the parts). Taken only when it hides at most half as many as `assumed`.
/// Deterministic.
ViewpointGuess guessViewpoint(const Points& points, const Vec3& assumed = Vec3::Zero());

}  // namespace binpose
