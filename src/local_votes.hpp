#pragma once
// Local votes (binpose's default): each scene point votes once, with its neighbours within
// vote_radius, and every sub-group holding it reuses its candidates (voting.hpp).
#include <binpose/model_database.hpp>
#include "stage_settings.hpp"
#include <binpose/scene.hpp>
#include <binpose/voting.hpp>

#include "part_symmetry.hpp"

#include <memory>
#include <vector>

namespace binpose {

struct LocalVotes {
  std::unique_ptr<NeighbourhoodVoter> voter;  ///< null when local_votes is off
  std::vector<char> may_vote;                 ///< per scene point: a reference point of voter_spacing
  double setup_ms = 0;                        ///< time to set them up
};

/// The voter over the scene (partners one per partner_spacing cube) and the reference points
/// (one per voter_spacing cube; all without it). Empty when local_votes is off.
LocalVotes makeLocalVotes(const ModelDatabase& db, const PreparedScene& scene, const StageSettings& p,
                          const PartSymmetry& symmetry);

/// The voter over the scene, its partners one per partner_spacing cube (all without it) among
/// the points not flagged in `excluded` (all when null).
std::unique_ptr<NeighbourhoodVoter> makeVoter(const ModelDatabase& db, const PreparedScene& scene, const StageSettings& p,
                                              const PartSymmetry& symmetry, const std::vector<char>* excluded = nullptr);

}  // namespace binpose
