"""The fixed wording of reproduce's REPORT.md, as templates the report's inputs fill in."""

from __future__ import annotations

from string import Template

TITLE = "Reproducing She & Tian, section 4, on equal terms"
SCENE = Template(
    "Scenario `$scenario` ($area area with an obstacle field)$crossing, the three controllers "
    "behind the same planner, seeds $seeds, runtime `$runtime`. Networks: $networks."
)

# what is compared, plainly, and the rules every controller shares ($r_min, $rho0 in m)
TERMS = tuple(
    Template(t)
    for t in (
        "- **The paper's contribution is the planner**: potential-field costs (eq. 6), a "
        "shortest path on the weighted graph, smoothing, and a NURBS path within the minimum "
        "turning radius (eqs. 9, 19-20). All three controllers here follow that same planned "
        'path. What the paper calls the "NURBS method" on the control side is, in tidelink, '
        "a path-following law of our own design (curvature feed-forward with line-of-sight "
        "feedback, services/control/controllers/nurbs_tracker.py): the paper does not publish "
        "its tracking law. The baselines are the published laws (Kanayama backstepping; an "
        "immune fuzzy PID). A verdict below therefore compares tracking laws behind one "
        "planner, not planners.",
        "- **Same delay compensation**: every case runs either with the pose predicted "
        "forward by the estimate's age and the expected downlink delay for all three "
        "controllers (`controller.delay_compensation = true`), or for none (the "
        "`-uncompensated` cases).",
        "- **Same speed profile** (services/control/controllers/speed.py): one cruise cap, one "
        "acceleration ramp and one slow-down rule (curvature preview and the end of the path) "
        "for all three; Backstepping's k_x e_x term may slow it below the profile, never push "
        "it past the cruise cap. Travel-time differences come from steering.",
        "- **Same plant**: the vehicle cannot turn tighter than R_min = $r_min m "
        "(|w| <= |v| / R_min, the bound of eq. 11 made physical), whatever the controller "
        "asks; each controller also caps its own yaw-rate command by the speed the vehicle has.",
        "- **Same gains search** (below), and the same planned path in every seed (the first "
        "plan is made once the first obstacle tracks are in).",
        "- **The paper's pipeline**: eq. (2) mean filter and eq. (3) lag are on in every case "
        "but the ablation `lossy-no-prefilter`.",
        "- **Safety**: a run succeeds when it reaches the goal without contact and never "
        "comes inside the safety distance rho0 = $rho0 m (surface to surface, eq. 6); "
        "a run inside rho0 without contact is a *rho0 breach*, counted apart from a "
        "collision.",
        "- **Control actions** are velocity commands at the planner's fixed rate (10 Hz), so "
        'their count is 10 x the travel time in seconds: "more control actions" (the paper\'s '
        'conclusion (i)) and "faster" are one measurement, not two claims. It is reported, '
        "not graded.",
    )
)
READING = Template(
    "A control action is *on the optimal path* when the true vehicle is within "
    "$on_path_tol m of the first planned path as it is issued; a *return to the "
    "path* is a re-entry into that band after leaving it (services/mission/metrics.py). "
    "Values are the mean [95 % interval] over the seeds, the bootstrap percentile "
    "interval of the mean (within the values' range); success is a Wilson 95 % "
    "interval; travel time only over runs that reached the goal."
)
REPLANNING = (
    "Planning: the planner replans as in a normal mission (deviation, moving "
    "obstacles); the optimal path is its first plan, identical for the three "
    "controllers, but later plans may differ between them."
)
ONE_PLAN = (
    "Planning: the first plan is kept for the whole run (`planner.min_replan_interval_s"
    " = 1e9`), so the three controllers follow one and the same planned path, as in "
    "the paper; `--replan` lets the planner replan as in a normal mission. The "
    "crossing scenario always replans: that is what it exercises."
)

NO_SEARCH = (
    "The scenario's gains for all three controllers (no search was run: "
    "`--no-tune`; by default `tidelink reproduce` runs the same search for each)."
)
SEARCH = Template(
    "Chosen by the same search for every controller "
    "(services/experiments/reproduction/tuning.py): its "
    "two principal path-following gains, each scaled by powers of $step around the "
    "scenario's values, on a perfect network, tuning seeds $seeds (disjoint "
    "from the evaluation seeds), with the comparison's pipeline and speed profile. Rule: "
    "highest success rate (goal, no contact, never inside rho0), then lowest RMS "
    "cross-track error to the path in force (the controller's own tracking error), then "
    "shortest travel time. Each grid starts at factors "
    "$first and grows in any direction where the "
    "choice lies on its edge, up to "
    "$limit; a point the "
    "configuration refuses (e.g. a gain below its validated minimum) counts as no run."
)

VERDICTS = (
    "Verdicts of the NURBS method against both baselines (holds: on the claimed side of "
    "both with 95 % intervals apart; in the means: on the claimed side, intervals "
    "overlap; in part: against one baseline only):"
)
CONSTRAINT = Template(
    "- $name: $breaches rho0 breaches and $contacts collisions in "
    "$runs runs; highest mean executed curvature after the start $curvature 1/m "
    "(1/R_min = $limit 1/m), at most $above s above it on "
    "average (from rest included)."
)
CORRIDOR = Template(
    "Runs that left the optimal path's corridor (max XTE to it > $corridor m, "
    "the planner's corridor half-width): $what"
)
CORRIDOR_LEFT = "Such runs dominate the XTE-to-optimal-path means and their wide intervals."

CANNOT_COMPARE = (
    '- The paper counts "control points" of a MATLAB simulation whose control rate is '
    "not stated; our planner commands at 10 Hz, so our counts are about 10 x the travel "
    "time in seconds.",
    "- The paper's travel times (4.98 to 32.5 min for about 100 m) imply mean speeds of "
    "0.05 to 0.33 m/s; our vehicle cruises at the scenario's cruise speed, so absolute "
    "times differ by design: the ratios between controllers are the comparable quantity.",
    "- The paper gives no gains for its baselines; ours are stated above.",
)
