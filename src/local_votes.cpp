// Set-up of the local votes: the voter over the scene and its reference points.
#include "local_votes.hpp"

#include "stopwatch.hpp"

namespace binpose {

namespace {

/// The points not flagged in `excluded` (all when null), one per `spacing` cube (all with 0;
/// empty, meaning all, when neither thins them).
std::vector<std::uint32_t> partnersOf(const Points& points, const std::vector<char>* excluded, float spacing) {
  if (excluded == nullptr) return spacing > 0 ? voxelSubsample(points, spacing) : std::vector<std::uint32_t>{};
  std::vector<std::uint32_t> left;
  Points at;
  for (std::uint32_t i = 0; i < points.size(); ++i)
    if (!(*excluded)[i]) {
      left.push_back(i);
      at.push_back(points[i]);
    }
  if (!(spacing > 0)) return left;
  std::vector<std::uint32_t> partners;
  for (const auto k : voxelSubsample(at, spacing)) partners.push_back(left[k]);
  return partners;
}

}  // namespace

std::unique_ptr<NeighbourhoodVoter> makeVoter(const ModelDatabase& db, const PreparedScene& scene, const StageSettings& p,
                                              const PartSymmetry& symmetry, const std::vector<char>* excluded) {
  return std::make_unique<NeighbourhoodVoter>(db, scene.points, scene.normals, p.vote_radius, symmetry.candidatesPerPoint(p),
                                              partnersOf(scene.points, excluded, p.partner_spacing), p.candidate_spacing,
                                              symmetry.votingOrbits(), mildOutliers(p));
}

LocalVotes makeLocalVotes(const ModelDatabase& db, const PreparedScene& scene, const StageSettings& p,
                          const PartSymmetry& symmetry) {
  LocalVotes out;
  if (!p.local_votes) return out;
  const auto t0 = Clock::now();
  out.voter = makeVoter(db, scene, p, symmetry);
  out.may_vote.assign(scene.points.size(), p.voter_spacing > 0 ? 0 : 1);
  if (p.voter_spacing > 0)
    for (const auto i : voxelSubsample(scene.points, p.voter_spacing)) out.may_vote[i] = 1;
  out.setup_ms = msSince(t0);
  return out;
}

}  // namespace binpose
