// Beyond the thesis: a detection that the scan shows by one flat face, placed along that face.
//
// Point-to-plane ICP (5.2.6) fixes such a pose across the face, and nothing fixes it along it:
// a cap seen down its axis shows a disc, a part lying flat one face, and the steep sides that
// would hold it in place are seen edge-on or not at all. What does fix it is the face's outline:
// beyond a right pose's edge the scan falls away, and a pose shifted along the face lays model
// points over that drop (free space: contradicted) and leaves scan points of the face
// unexplained. So the pose moves along the face while the score (supported minus contradicted)
// grows. On the structured-light bins ICP leaves such caps up to 4-6 mm off along their disc.
#include "face_slide.hpp"

#include <tbb/parallel_for.h>

namespace binpose {

namespace {

/// Steps along the face: from this many verification tolerances, halved down to kLeastStep.
constexpr float kFirstStep = 0.5f;
constexpr float kLeastStep = 0.12f;
/// Moves of one step size at most (a pose a few mm off moves a few steps).
constexpr int kMostMoves = 12;

/// `pose` moved along the plane with normal `normal` while its score grows; `score` is the start's
/// and then the result's.
Pose slid(const Matcher& m, Pose pose, const Vec3& normal, float& score) {
  const Vec3 u = normal.unitOrthogonal(), w = normal.cross(u);
  const Vec3 directions[4] = {u, -u, w, -w};  // each next to its opposite (j ^ 1)
  const float tolerance = m.p.verify_tolerance;
  for (float step = kFirstStep * tolerance; step >= kLeastStep * tolerance; step *= 0.5f) {
    int back = -1;  // the direction back to where the last move came from: its score is lower
    for (int k = 0; k < kMostMoves; ++k) {
      bool better = false;
      for (int j = 0; j < 4; ++j) {
        if (j == back) continue;
        Pose moved = pose;
        moved.translation() += step * directions[j];
        const float s = m.evidence.evaluate(moved, m.scored_model, tolerance, m.db.model().sample_radius).score();
        if (s > score) {
          score = s;
          pose = moved;
          better = true;
          back = j ^ 1;
        }
      }
      if (!better) break;
    }
  }
  return pose;
}

}  // namespace

void slideAlongFaces(std::vector<Detection>& detections, const Matcher& m) {
  tbb::parallel_for(std::size_t{0}, detections.size(), [&](std::size_t i) {
    Detection& d = detections[i];
    std::vector<std::uint32_t> support;
    float score = m.scoredEvidence(d.pose, support).score();
    const std::optional<Plane> face = m.faceOf(support);
    if (!face) return;
    d.pose = slid(m, d.pose, face->normal, score);
    d.score = score;
  });
}

}  // namespace binpose
