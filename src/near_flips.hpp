#pragma once
// Beyond the thesis: a part's near-symmetric half turns, found offline.
//
// Many parts are nearly symmetric under a half turn: a bracket's plate over its width, a cap end
// over end about a line across its axis (its outer wall onto itself), a square part about a
// diagonal. On a noisy scan the side that tells the two apart is often unresolved, and a clique
// lays the part over its turned self: 27 detections on 72 simulated bins (structured light, time
// of flight, industrial) lie 150-180 degrees off their copy, at its place.
#include "model_shape.hpp"

#include <binpose/pose.hpp>

#include <vector>

namespace binpose {

/// The model's near-symmetric turns, best first: half turns about lines through the centroid
/// from an even spread of directions, each aligned by ICP against the model itself; kept where
/// most of the model then lies on itself, the turn is not the identity (or a symmetry already
/// matched, `shape`) and is not another of those kept.
std::vector<Pose> nearFlips(const Points& points, const Points& normals, const ModelShape& shape);

struct ModelFace;

/// The half turns that lay one of the model's flat `faces` on itself, turned over, about each of
/// its two principal axes through its centre: the rest of the part then lies on that face's other
/// side. A copy that shows the sensor one large face (a bracket's plate seen face-on, the other
/// plate behind it) shows little of which side its body lies on, and a clique may lay the part
/// over its mirror image across that face. Two faces of one plate (its sides, a thickness apart)
/// give one turn, about the line midway. Half turns the same as `near` (nearFlips) give way to
/// these, which lay the face exactly; the rest of `near` come first.
std::vector<Pose> withFaceFlips(std::vector<Pose> near, const std::vector<ModelFace>& faces, const ModelShape& shape);

}  // namespace binpose
