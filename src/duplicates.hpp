#pragma once
// The last stage: the verified hypotheses, best first, one per object.
#include "model_shape.hpp"

#include <binpose/detector.hpp>

#include <vector>

namespace binpose {

/// Best first (by score), the hypotheses that are distinct objects: a hypothesis is kept unless
/// it is another pose of an object already kept (as suppressDuplicates).
std::vector<Hypothesis> distinctObjects(std::vector<Hypothesis> hypotheses, std::size_t scan_size, const ModelShape& shape);

/// Best first (by score), keeps a detection unless it is another pose of an object already
/// kept: over a quarter of its supporting scan points are claimed (each scan point belongs to
/// one object), or a twentieth are and its model mostly overlaps a kept one's (a
/// near-symmetric flip, say).
std::vector<Detection> suppressDuplicates(std::vector<Hypothesis> hypotheses, std::size_t scan_size, const ModelShape& shape);

}  // namespace binpose
