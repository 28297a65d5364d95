// Set-up of the local votes: the voter over the scene and its reference points.
#include "local_votes.hpp"

#include "stopwatch.hpp"

namespace binpose {

LocalVotes makeLocalVotes(const ModelDatabase& db, const PreparedScene& scene, const StageSettings& p,
                          const PartSymmetry& symmetry) {
  LocalVotes out;
  if (!p.local_votes) return out;
  const auto t0 = Clock::now();
  std::vector<std::uint32_t> partners;
  if (p.partner_spacing > 0) partners = voxelSubsample(scene.points, p.partner_spacing);
  out.voter =
      std::make_unique<NeighbourhoodVoter>(db, scene.points, scene.normals, p.vote_radius, symmetry.candidatesPerPoint(p),
                                           partners, p.candidate_spacing, symmetry.votingOrbits(), mildOutliers(p));
  out.may_vote.assign(scene.points.size(), p.voter_spacing > 0 ? 0 : 1);
  if (p.voter_spacing > 0)
    for (const auto i : voxelSubsample(scene.points, p.voter_spacing)) out.may_vote[i] = 1;
  out.setup_ms = msSince(t0);
  return out;
}

}  // namespace binpose
