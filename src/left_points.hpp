#pragma once
// Beyond the thesis: a last look at what both passes left unexplained (StageSettings::revote_left).
//
// A point votes once, with every partner within vote_radius, and in a full bin most partners lie
// on its neighbours: at a copy among many, few voters hold the right model point among their
// candidates, and the sub-groups there find no clique. Once the copies around it are found and
// their points removed (5.2.6), its points vote again among those left alone, and the sub-groups
// still made mostly of such points run again.
#include "group_schedule.hpp"
#include "part_symmetry.hpp"
#include "subgroup_matcher.hpp"

#include <cstdint>
#include <vector>

namespace binpose {

/// The sub-groups half or more of whose points are left (neither removed nor within sigma_dist
/// of a detection scoring explain_score), run again through `matcher` with the points left as
/// the only vote partners; of the detections they add, those under retry_min_score are dropped.
/// Returns the pass's times (its voter's set-up counted as local votes).
ScheduleTimes revoteLeftPoints(const ModelDatabase& db, const StageSettings& p, const ModelShape& shape,
                               const PartSymmetry& symmetry, const PreparedScene& scene, const Matcher& matcher,
                               const std::vector<std::vector<std::uint32_t>>& groups, const std::vector<char>& may_vote,
                               MatchState& state);

}  // namespace binpose
