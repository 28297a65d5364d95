#pragma once
// One sub-group through the thesis's steps (5.2.3-5.2.5): votes (4.3-4.4), the largest
// consistent clique (4.5), Horn's pose (4.6), then verification: pre-screen, ICP and score.
#include "model_shape.hpp"
#include "part_symmetry.hpp"

#include <binpose/detector.hpp>
#include <binpose/pixel_neighbours.hpp>
#include <binpose/planes.hpp>
#include <binpose/refine.hpp>
#include <binpose/scene.hpp>
#include <binpose/voting.hpp>

#include <functional>
#include <optional>
#include <span>
#include <vector>

namespace binpose {

/// Another clique's closed-form pose and its score at the ICP gate (prescore).
struct OtherPose {
  Pose pose;
  float prescore = 0;
};

/// Another clique's pose, refined and scored beside the first clique's (alternative_cliques).
struct OtherHypothesis {
  Pose start;               ///< its closed-form pose
  Hypothesis hypothesis;    ///< refined and scored
  Evidence evidence;        ///< its counts
  std::vector<Pose> path;   ///< ICP's pose after each step
};

/// What one sub-group gave on the scene as it stood when it ran. Sub-groups run side by side in
/// batches and are taken in their order afterwards (group_schedule.hpp).
struct GroupOutcome {
  std::vector<std::uint32_t> members;               ///< its points not removed when it ran
  bool ran = false;                                 ///< enough members to vote
  std::vector<Correspondence> clique;               ///< the clique's pairs (empty: no pose)
  std::vector<Pose> poses;                          ///< the clique's closed-form pose, then its alternatives
                                                    ///< (a body of revolution's other axis sign)
  std::vector<Pose> other_poses;                    ///< the poses of other cliques (alternative_cliques)
  std::optional<OtherHypothesis> other;             ///< the best of them, verified; taken instead of the
                                                    ///< hypothesis when it scores more (GroupSchedule::take)
  bool screened_out = false;                        ///< the pose failed the pre-screen
  bool pending = false;                             ///< a pose not seen when it ran, not verified yet (Matcher::verify)
  std::vector<Pose> path;                           ///< ICP's pose after each step
  bool refound = false;                             ///< ICP came to an object already found (and stopped there)
  bool all_voters = false;                          ///< every member's candidates taken, not only the voters'
  bool reflected = false;                           ///< the pose of a mirror-image clique, reflected (Matcher::match)
  int largest_clique = 0;                           ///< size of the first clique searched (0: none searched)
  Hypothesis hypothesis;                            ///< refined and scored (when the clique gave a pose that passed)
  Evidence evidence;                                ///< the hypothesis's counts (its score, without grazing, visible support)
  std::optional<bool> stands;                       ///< the hypothesis's Matcher::stands, where verifying judged it (turn_over)
  double vote_ms = 0, match_ms = 0, refine_ms = 0;  ///< the thread's time in each stage
};

/// The buffers and the outcome of one place in a batch (the outcome is kept until it is taken).
struct Slot {
  Slot(const ModelDatabase& db, const StageSettings& p, const PartSymmetry& symmetry)
      : voter(db, symmetry.candidatesPerPoint(p), p.candidate_spacing, symmetry.votingOrbits(), mildOutliers(p)) {}
  Voter voter;
  std::vector<Correspondence> candidates;
  std::vector<Correspondence> clique;  ///< the clique being fitted
  CliqueBuffers buffers;
  GroupOutcome outcome;
};

/// Everything a sub-group reads (nothing it writes is shared).
struct Matcher {
  const ModelDatabase& db;
  const StageSettings& p;
  const PreparedModel& icp_model;       ///< ICP's share of the model points
  const PreparedModel& prescore_model;  ///< a share of those, for prescore()
  const PreparedModel& scored_model;    ///< all of them, for the score
  const PreparedScene& scene;
  const PointCloud& scan;
  const PointGrid& scan_grid;
  const PixelNeighbours* pixels;  ///< the scan's, for ICP's searches (null: the grid alone)
  const SceneEvidence& evidence;
  const NeighbourhoodVoter* local;    ///< the local votes (null: each sub-group votes, 4.3)
  const std::vector<char>& may_vote;  ///< with local votes, the points of voter_spacing
  const PartSymmetry& symmetry;       ///< none, a body of revolution's orbits, or n-fold symmetry
  /// True when a pose is another of an object already found (explain_score), or close to a
  /// clique pose already verified (tried_share): its clique is not verified again.
  std::function<bool(const Pose&)> seen;
  /// True when a pose is another of an object already found: ICP stops there (refound).
  std::function<bool(const Pose&)> found;

  /// prepare(), then verify() when it asks for it.
  void run(std::span<const std::uint32_t> group, const std::vector<char>& removed, Slot& s, bool all_voters,
           const GroupOutcome* earlier = nullptr, ParallelVoter* parallel = nullptr) const {
    if (prepare(group, removed, s, all_voters, earlier, parallel)) verify(s);
  }

  /// Votes, clique and pose of one sub-group with the scene points not yet `removed`; true when
  /// its pose is to be verified (the outcome is then `pending`). A clique whose pose (or one of
  /// its alternatives) is seen() is not verified. The pose, ICP and score depend on the clique's
  /// pairs alone: when `earlier` (a run of the same sub-group with more points) verified the
  /// same clique, its verdict is taken instead. `parallel`: votes with it instead of the slot's
  /// voter, on all cores. `all_voters`: with local votes, the candidates of every member, not
  /// only of the voters of voter_spacing.
  bool prepare(std::span<const std::uint32_t> group, const std::vector<char>& removed, Slot& s, bool all_voters,
               const GroupOutcome* earlier = nullptr, ParallelVoter* parallel = nullptr) const;

  /// Pre-screen, ICP and score of a pending outcome's pose.
  void verify(Slot& s) const;
  /// ICP of this many steps against the scan, gated and scored as verification does.
  IcpParams icpParams(int iterations) const;
  /// The final score's evidence for a pose on all model points, the supporting scan points added
  /// to `support` (sorted, distinct).
  Evidence scoredEvidence(const Pose& pose, std::vector<std::uint32_t>& support) const;
  /// Whether a verified pose scoring `score` with evidence `e` and the supporting scan points
  /// `support` stands as a detection: at least min_score, supported on min_visible_support of
  /// what the scan could show, not sunk into the bin (sunk) nor behind its own face
  /// (sunkBehindFace), and standing out of the scan at its outline (outlineStandsOut; `laid`: a
  /// pose laid on one flat face).
  [[nodiscard]] bool stands(const Pose& pose, float score, const Evidence& e, std::span<const std::uint32_t> support,
                            bool laid = false) const {
    return refusal(pose, score, e, support, laid) == Refusal::none;
  }
  /// The first of stands()'s tests that the pose fails (Refusal::score: under min_score), or none.
  [[nodiscard]] Refusal refusal(const Pose& pose, float score, const Evidence& e, std::span<const std::uint32_t> support,
                                bool laid = false) const;
  /// Whether the pose, when its support lies on one plane (`face`: faceOf of its support), has
  /// more than a tenth of its visible points behind that plane where the scan shows the plane in
  /// front of them (SceneEvidence::sunkBehind), and those are more than a quarter of the points
  /// the scan hides (e.occluded): a body sunk into a surface that goes on from its face.
  [[nodiscard]] bool sunkBehindFace(const Pose& pose, const std::optional<Plane>& face, const Evidence& e) const;
  /// Whether the posed part's outline tells it from the scan around it (SceneEvidence::outline):
  /// the scan's surface does not go on past it at more than max_outline_share of it (where the
  /// support lies on more than one plane, many_faces_outline_share), and where the support lies
  /// on one plane (`face`: faceOf of the support), the scan falls away behind at least
  /// min_outline_drop of it. A pose `laid` on one flat face (face_hypotheses.hpp) must also
  /// fall away behind 40 % of it, whatever those two settings.
  [[nodiscard]] bool outlineStandsOut(const Pose& pose, const std::optional<Plane>& face, bool laid = false) const;
  /// The plane that the support's scan points lie on, when 80 % of them or more lie within two
  /// verification tolerances of their least-squares plane: the scan shows the part by one flat
  /// face. None otherwise.
  [[nodiscard]] std::optional<Plane> faceOf(std::span<const std::uint32_t> support) const;
  /// Whether more than max_sunk_share of the posed model lies inside the bin's planes
  /// (SceneEvidence::sinking), where no part can be.
  [[nodiscard]] bool sunk(const Pose& pose) const;
  /// The pose's score at the ICP gate on prescore_model (a second pass's: without grazing points).
  [[nodiscard]] float prescore(const Pose& pose, bool second_pass) const;

 private:
  /// The candidate correspondences of the outcome's members; false when a second pass has nothing new.
  bool collectVotes(Slot& s, bool all_voters, ParallelVoter* parallel) const;
  /// Clique and closed-form pose (a refused mirror-image clique gives way to the next, up to
  /// mirror_retries times; when none fits, the first such clique of a mirror-symmetric part
  /// fits with its model points reflected in the part's mirror plane); false when there is none.
  /// The pose goes into the outcome.
  bool match(Slot& s) const;
  /// The closed-form poses (4.6) of the candidates at `vertices`, best first, their pairs in the
  /// slot's clique; empty when there is none. `reflected`: as PartSymmetry::solve.
  std::vector<PoseFit> posesOf(Slot& s, std::span<const int> vertices, bool reflected = false) const;
  /// The closed-form pose of a clique's pairs into the outcome; false when there is none.
  bool fitClique(Slot& s, const CliqueResult& clique, bool reflected = false) const;
  /// The poses of the next alternative_cliques largest cliques, each without the pairs of the
  /// one before (`taken`, isolated in `graph`), into the outcome's other_poses.
  void addAlternativeCliques(Slot& s, Graph& graph, std::vector<int> taken) const;
  /// The scan decides between a clique's poses, and screens out one far from it; false when screened out.
  bool prescreen(Slot& s) const;
  /// Of the other cliques' poses, the one scoring best at the ICP gate, when it scores at least
  /// alternative_min_score.
  std::optional<OtherPose> otherCliquePose(const Slot& s) const;
  /// ICP and score of that pose into the outcome's `other`.
  void verifyOther(Slot& s, const Pose& start) const;
  /// Pre-screen, ICP and score of the outcome's pose (and of the other cliques' best).
  void screenRefineScore(Slot& s) const;
  /// A body of revolution's verified pose that does not stand, turned end over end (turnedOver);
  /// it replaces the outcome's when it stands and scores at least alternative_min_score (true).
  bool turnOver(Slot& s) const;
};

}  // namespace binpose
