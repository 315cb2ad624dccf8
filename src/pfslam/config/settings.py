"""The configurations: typed, frozen, validated when built (SlamConfig and its sections,
LocalizerConfig, CalibrationConfig). Each numeric field declares its bounds (``bounded``)
and :func:`~pfslam.config.checks.check_config` checks them all in field order, a section's
fields by the config that holds it (a section built alone is a plain record); only the few
checks across fields are written out, in ``__post_init__``."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pfslam.config.checks import MAX_PARTICLES, _doc, bounded, check_config
from pfslam.config.choices import (
    Backend,
    GlobalStart,
    OdomModel,
    ParticleWeight,
    PoseEstimate,
    ResampleMethod,
    RobustLoss,
    ScoringMap,
    SensorModel,
    SlamFilter,
)
from pfslam.errors import ConfigError


@dataclass(frozen=True)
class MapConfig:
    resolution: float = bounded(0.05, ge=0.001)  # m per cell
    # A hit must raise a cell towards occupied and a beam passing through lower it.
    l_occ: float = bounded(3.0, gt=0.0)  # log-odds added to the cell a beam ends in
    l_free: float = bounded(-1.0, lt=0.0)  # log-odds added to each cell a beam passes through
    l_clamp: float = bounded(120.0, gt=0.0)  # cells are clamped to +-l_clamp
    initial_size: float = bounded(20.0, gt=0.0)  # m, the grid grows as needed


@dataclass(frozen=True)
class MotionConfig:
    sigma_x: float = bounded(0.01, ge=0.0)  # m per ref_interval
    sigma_y: float = bounded(0.01, ge=0.0)  # m per ref_interval
    sigma_theta_deg: float = bounded(0.5, ge=0.0)  # deg per ref_interval
    ref_interval: float = bounded(0.25, gt=0.0)  # s (10 scans at 40 Hz)
    trans_k: float = bounded(0.0, ge=0.0)  # extra x/y noise per metre travelled (m/m), added in quadrature
    rot_k: float = bounded(0.0, ge=0.0)  # extra heading noise per radian turned (rad/rad)
    axle: float = bounded(0.33, gt=0.0)  # m, differential drive only
    k_left: float = bounded(0.05, ge=0.0)  # wheel travel noise per metre, differential drive only
    k_right: float = bounded(0.05, ge=0.0)


@dataclass(frozen=True)
class SensorConfig:
    ground_z: float = 0.15  # m, points lower than this are floor hits
    max_hits: int = bounded(400, lo=1)  # hits used to score a particle (evenly subsampled)
    saturation: float = bounded(6.0, gt=0.0)  # log-odds at which a cell counts fully as wall (+1) or free (-1)
    temperature: float = bounded(2.0, gt=0.0)  # log-weight = score / temperature
    # scoring_map "cells": a hit in confirmed free space scores -free_weight (0..1)
    free_weight: float = bounded(0.0, ge=0.0, le=1.0)
    # What hits are scored on (ScoringMap): "cells", "field", or "auto": "field" for steps
    # that moved more than field_auto_m or turned more than field_auto_deg since the last
    # scan, "cells" otherwise.
    scoring_map: ScoringMap = ScoringMap.AUTO
    field_auto_m: float = bounded(0.2, ge=0.0)
    field_auto_deg: float = bounded(5.0, ge=0.0)
    field_sigma: float = bounded(0.1, gt=0.0)  # m, width of the smoothed wall map
    field_threshold: float = 1.0  # log-odds above which a cell counts as wall for the field
    field_refresh_m: float = bounded(0.25, ge=0.0)  # rebuild the field after this much motion (m) ...
    field_refresh_deg: float = bounded(5.0, ge=0.0)  # ... or turn (deg) ...
    field_refresh_scans: int = bounded(40, lo=1)  # ... or this many scans, whichever comes first


@dataclass(frozen=True)
class LocalSearchConfig:
    # Each particle also tries the offsets of a local grid and moves to its best one: the
    # filter then follows motions the odometry gets wrong by up to radius_cells cells and
    # theta_steps * theta_step_deg degrees per scan (fast turns with slipping wheels),
    # at (2r+1)^2 (2k+1) times the scoring cost: bounded so a typo cannot hang the run.
    enabled: bool = False
    radius_cells: int = bounded(2, lo=0, hi=20)  # x/y offsets of -r..r cells
    theta_steps: int = bounded(4, lo=0, hi=45)  # heading offsets of -k..k steps
    theta_step_deg: float = bounded(1.0, gt=0.0)


@dataclass(frozen=True)
class RbpfConfig:
    """Settings of the Rao-Blackwellized filter (``filter: rbpf``); names after GMapping's
    where it has one (srr, srt, str, stt; lstep, astep; sigma, lsigma)."""

    # A map update after this much travel since the last (0.5 m: chosen by a sweep of the shared
    # logs and the simulated walks, bench/defaults/updates*.yaml) ...
    update_m: float = bounded(0.5, ge=0.0)
    update_deg: float = bounded(10.0, ge=0.0)  # ... or this much turn
    # Motion noise at an update, in proportion to the odometry since the last one.
    noise_xy_per_m: float = bounded(0.05, ge=0.0)  # srr: m per m travelled
    noise_xy_per_rad: float = bounded(0.05, ge=0.0)  # srt: m per rad turned
    noise_theta_per_m: float = bounded(0.05, ge=0.0)  # str: rad per m travelled
    noise_theta_per_rad: float = bounded(0.05, ge=0.0)  # stt: rad per rad turned
    match_hits: int = bounded(180, lo=1)  # hits used to match and weigh a scan (evenly subsampled)
    # m: longer beams clear free space up to here and map no wall; -1: per log kind (see
    # resolve_filter): WHEELED_MAP_RANGE (40) on wheeled logs, whose planar lasers are level (the
    # campus's streets need the facades 20-40 m away; Intel and csail better, FR079 as good,
    # the wheeled buildings as good but one seed, seeds 0-4), 20 on THOR logs (a swaying head's far hits: the
    # office loop drifting 0.8 deg/m 0.012 -> 0.016 m aligned at 30-40 m) and unknown ones.
    # bench/open/map_range*.yaml, docs/method.md § Open ground.
    map_range: float = bounded(
        -1.0,
        gt=0.0,
        unless=-1.0,
        what="-1 (per log kind) or a distance in metres",
        doc="-1: per log kind (40 m on wheeled logs, 20 m on THOR logs)",
    )
    # m: a level laser's beam that returned nothing clears free space up to here (at most
    # map_range; 0: such beams are left out)
    no_return_m: float = bounded(0.0, ge=0.0)
    # A beam whose path, at a particle's match, crosses a wall that particle's map is sure of
    # (two hits' log-odds; up to health_tolerance short of the beam's end) counts in its weight as
    # a hit with no wall near (floor): the hits matched, and the no-return beams to no_return_m.
    # Off: worse on the campus (3 of 3 seeds) and infinite-corridor (2 of 3), mixed on Intel and
    # csail, runs 3-63 % longer (bench/open/see_through.json).
    see_through: bool = False
    # At an update whose scan holds fewer than 20 hits within map_range (blind: nothing to match),
    # every particle follows the odometry with no noise and no weight (false: matched and weighed
    # as any update, so the path follows whichever particle's noise happened to be best). The
    # campus seed 0: 78.2 -> 15.5 m aligned; Intel, csail, the wheeled and THOR buildings, the
    # demo's office (seeds 0-4) and a rough THOR walk: the same to the bit (never blind).
    blind_follow: bool = True
    # After this much travel following the odometry (m; blind updates; 0: never), the first scans
    # that see again are searched for in the best particle's map over the window such a stretch
    # may have drifted (reacquire_deg_per_m of heading a metre and what it throws sideways, at
    # most reacquire_max_m / reacquire_max_deg), and the particles moved there rigidly where the
    # match is good and unique (pfslam.filters.reacquire; docs/method.md § Open ground).
    reacquire_m: float = bounded(20.0, ge=0.0)
    # Where the particles follow the odometry (blind updates), its scale, turn scale and heading
    # bias as the matched updates before show them are taken out (pfslam.filters.drift)
    undo_drift: bool = True
    reacquire_deg_per_m: float = bounded(0.5, ge=0.0)
    reacquire_max_m: float = bounded(100.0, ge=0.0)
    reacquire_max_deg: float = bounded(45.0, ge=0.0, le=180.0)
    sigma: float = bounded(0.05, gt=0.0)  # m, width of the match kernel exp(-d^2 / 2 sigma^2)
    radius: int = bounded(1, lo=0, hi=5)  # cells searched around each hit for the nearest wall (1: 3 x 3)
    lstep: float = bounded(0.05, gt=0.0)  # m, the matcher's first x/y step
    astep_deg: float = bounded(3.0, gt=0.0)  # deg, its first heading step
    refinements: int = bounded(2, lo=0, hi=10)  # halvings of the steps
    # Gauss-Newton steps on the smooth score after the climb (0: none; see kernels/refine.py)
    refine: int = bounded(3, lo=0, hi=20)
    weight: ParticleWeight = _doc(
        ParticleWeight.NORMALISER,
        "peak: a particle's log-weight gains the scan's log-likelihood at its match; normaliser: "
        "times the integral of its match's Gaussian under the odometry's (GMapping's improved proposal)",
    )
    lsigma: float = bounded(0.075, gt=0.0)  # m, width of the likelihood kernel
    floor: float = bounded(0.05, gt=0.0, le=1.0)  # likelihood of a hit with no wall near it
    temperature: float = bounded(20.0, gt=0.0)  # log-weight += log-likelihood / temperature
    # Weight of the odometry's motion prior in the match (1: the match score read as a
    # log-likelihood x temperature; 0: none, GMapping's way; -1: per log kind, see
    # resolve_filter: WHEELED_MATCH_PRIOR on wheeled logs, 0 on THOR logs). 0.1 stops Intel's
    # first match (a 34 deg turn in place, walls 1.5 m away) sliding 0.24 m along its
    # corridor: raw ATE 0.329 -> 0.117 m, aligned 0.052 -> 0.047 m; but on the THOR demo it
    # holds back real corrections (0.021 -> 0.041-0.057 m on seeds 0, 12, 17).
    match_prior: float = bounded(
        -1.0,
        ge=0.0,
        le=100.0,
        unless=-1.0,
        what="-1 (per log kind) or a number",
        doc="-1: per log kind (0.1 on wheeled logs, 0 on THOR logs)",
    )
    # The health (pfslam.filters.health): how well each update's scan fits the best
    # particle's own map at its match.
    health_tolerance: float = bounded(0.15, gt=0.0, doc="m: a hit this near a mapped wall is explained by it")
    health_degraded: float = bounded(0.5, ge=0.0, le=1.0, doc="quality below which the SLAM health is degraded")
    health_lost: float = bounded(0.2, ge=0.0, le=1.0, doc="quality below which the SLAM health is lost")


@dataclass(frozen=True)
class GraphConfig:
    """The loop-closing back end (``backend: graph``): the filter's path cut into nodes,
    consecutive nodes into submaps, each node matched against the older submaps near it by
    branch and bound, and a pose graph with a robust loss solved on GTSAM."""

    node_m: float = bounded(0.5, ge=0.0, doc="m: a new node after this much travel since the last ...")
    node_deg: float = bounded(10.0, ge=0.0, doc="... or this much turn (deg)")
    node_points: int = bounded(
        200, lo=10, hi=5000, doc="scan points kept per node for matching (on a 2-cell grid, then evenly subsampled)"
    )
    submap_nodes: int = bounded(
        20, lo=2, hi=10000, doc="nodes per submap; a new submap starts every half of it, so each node is in two"
    )
    max_range: float = bounded(
        15.0, gt=0.0, doc="m: hits farther than this from the sensor are left out of submaps and matching"
    )
    field_sigma: float = bounded(
        0.075, gt=0.0, doc="m: width of a submap's score field exp(-d^2 / 2 sigma^2) around its walls"
    )
    local_m: float = bounded(0.5, ge=0.0, le=50.0, doc="m: every node is searched over +- this much position error ...")
    local_deg: float = bounded(
        5.0, ge=0.0, le=180.0, doc="... and +- this much heading error (deg) against each submap near it"
    )
    window_m: float = bounded(
        8.0, ge=0.0, le=50.0, doc="m: where the local search finds none, the wide one covers up to +- this much ..."
    )
    window_deg: float = bounded(30.0, ge=0.0, le=180.0, doc="... and up to +- this much heading error (deg)")
    drift_per_m: float = bounded(
        0.1, ge=0.0, doc="m of position error the wide window allows per m travelled since the submap ..."
    )
    drift_deg_per_m: float = bounded(
        1.0, ge=0.0, doc="... and deg of heading error per m (both up to window_m / window_deg)"
    )
    search_every: int = bounded(
        0,
        lo=0,
        doc="only every k-th node is searched for loops (a sampling budget, as Cartographer's; 0: the fewest "
        "that keeps the nodes searched within search_budget)",
    )
    search_budget: int = bounded(300, lo=1, doc="... the most nodes searched when search_every is 0")
    wide_every: int = bounded(2, lo=1, doc="at most every k-th node gets the wide search")
    ambiguity: float = bounded(
        0.9,
        ge=0.0,
        lt=1.0,
        doc="a wide match is refused if one 0.5 m or 5 deg away scores this fraction of it (0: off)",
    )
    search_radius: float = bounded(
        4.0, ge=0.0, doc="m: a node is searched against submaps with a node this close (plus the window)"
    )
    submaps_per_node: int = bounded(3, lo=1, hi=100, doc="at most this many submaps searched per node (the nearest)")
    loops_per_node: int = bounded(2, lo=1, hi=100, doc="loop edges kept per node in the graph (the best-scoring)")
    passes: int = bounded(
        2, lo=1, hi=10, doc="search and solve this many times, each pass from the poses the last one solved"
    )
    min_gap_nodes: int = bounded(40, lo=1, doc="a loop joins nodes at least this many nodes apart")
    min_score: float = bounded(0.55, gt=0.0, lt=1.0, doc="mean field value a loop match needs (0..1) ...")
    wide_min_score: float = bounded(0.6, gt=0.0, lt=1.0, doc="... and a match of the wide search")
    node_sigma_m: float = bounded(0.02, gt=0.0, doc="m: the front end's relative-pose error between nodes, plus ...")
    node_sigma_per_m: float = bounded(0.005, ge=0.0, doc="... this much per metre between them (m/m)")
    node_sigma_deg: float = bounded(0.5, gt=0.0, doc="deg: its heading error, plus ...")
    node_sigma_deg_per_m: float = bounded(1.0, ge=0.0, doc="... this much per metre (deg/m)")
    loop_sigma_m: float = bounded(
        0.01, gt=0.0, doc="m: a loop match's position error at least, where its scan pins the pose (looser where not)"
    )
    loop_sigma_deg: float = bounded(0.1, gt=0.0, doc="deg: a loop match's heading error at least, likewise")
    surface_m: float = bounded(
        0.6,
        ge=0.0,
        le=5.0,
        doc="m: a loop's score surface is read over +- this much round its match (0: not read) ...",
    )
    surface_deg: float = bounded(2.0, ge=0.0, le=30.0, doc="... and +- this much heading (deg)")
    near_best: float = bounded(
        0.05,
        gt=0.0,
        lt=1.0,
        doc="every pose there scoring within this of the best (outside the peak) widens the loop's covariance "
        "towards it, weighed by how near it scores",
    )
    peak_m: float = bounded(0.1, ge=0.0, doc="m: the match's own peak, which widens nothing: this far ...")
    peak_deg: float = bounded(1.0, ge=0.0, doc="... and this much turned (deg)")
    ambiguous_m: float = bounded(
        0.25,
        gt=0.0,
        doc="m: a loop whose widened covariance leaves every direction of position more uncertain than this "
        "is refused as ambiguous",
    )
    scan_sigma_m: float = bounded(
        0.05,
        gt=0.0,
        doc="m: a hit's error across its wall, for what a scan pins of its pose (tight across a corridor, not along)",
    )
    scan_points: int = bounded(20, lo=1, hi=100000, doc="... counted as at most this many independent hits per scan")
    loose_along: float = bounded(
        3.0,
        ge=1.0,
        le=100.0,
        doc="the edges between nodes are up to this many times looser where their scan pins nothing (along corridors)",
    )
    # 3 (Karto's way) refused the loops that carry csail's corrections (seed 2: 0.137 -> 0.400 m
    # aligned) and let the twins world's aliased loops through all the same (they agree with
    # each other): off by default.
    chain_nodes: int = bounded(
        1,
        lo=1,
        hi=100,
        doc="a loop is kept only if this many nodes close by match the same place alike, as Karto does (1: off)",
    )
    chain_m: float = bounded(2.0, ge=0.0, doc="m: ... nodes within this much travel of each other ...")
    chain_tol_m: float = bounded(0.15, gt=0.0, doc="m: ... whose corrections agree to this ...")
    chain_tol_deg: float = bounded(2.0, gt=0.0, doc="... and this (deg)")
    match_levels: int = bounded(
        3,
        lo=0,
        hi=6,
        doc="each node's scan matched on those 1, 4, 16 ... nodes before it (this many spans): the graph's "
        "edges between nearby nodes and its submaps from those matches (0: the front end's path)",
    )
    step_paired: float = bounded(
        0.3,
        gt=0.0,
        le=1.0,
        doc="a match of two nearby nodes' scans pairing fewer than this fraction of its points (or 30) is not used ...",
    )
    step_rms_m: float = bounded(
        0.05,
        gt=0.0,
        doc="m: ... nor one (nor a loop's refinement) whose points lie farther than this from the walls ...",
    )
    step_gate_chi2: float = bounded(
        11.34, gt=0.0, doc="... nor one this far from the front end's relative pose (chi^2, 3 dof; 11.34: 99 %)"
    )
    slip_m: float = bounded(
        0.1,
        ge=0.0,
        doc="m: what the front end may have got wrong over a step between consecutive nodes no match backs ...",
    )
    slip_deg: float = bounded(4.0, ge=0.0, doc="... and in heading (deg: a turn where the scans barely overlap)")
    loop_paired: float = bounded(
        0.1,
        gt=0.0,
        le=1.0,
        doc="a loop's refinement pairs at least this fraction of the node's points (a submap is part of what it sees)",
    )
    better_score: float = bounded(
        0.02,
        ge=0.0,
        doc="the local window's best match replaces the match from the front end's guess if it scores this much "
        "more ...",
    )
    better_m: float = bounded(0.1, ge=0.0, doc="m: ... and lies this far from it ...")
    better_deg: float = bounded(2.0, ge=0.0, doc="... or is turned this much (deg)")
    unrefined_m: float = bounded(
        0.05, gt=0.0, doc="m: a loop whose match could not be refined point to line is at least this unsure ..."
    )
    unrefined_deg: float = bounded(1.0, gt=0.0, doc="... and this (deg)")
    pair_reach: int = bounded(
        40, lo=1, doc="nodes: loops are checked pairwise where their anchors and their nodes are this close"
    )
    match_edges: bool = _doc(
        True, "those matches are edges of the graph too (false: they place the submaps' nodes only)"
    )
    reweigh: bool = _doc(
        True,
        "after the first solve, weigh the front end's edges, the matches and the loops by how far each group "
        "erred (a front end that drifted is loosened, one that did not tightened)",
    )
    check_loops: bool = _doc(
        True,
        "refuse a loop far outside what the path between its nodes allows (Mahalanobis), and loops that "
        "disagree with the other loops near them (pairwise consistency)",
    )
    path_drift: float = bounded(
        0.02,
        ge=0.0,
        doc="m per m travelled: how far the front end may have drifted between two nodes, for those checks "
        "(where gate_chain is off, or the run has no edges between nearby nodes) ...",
    )
    path_drift_deg: float = bounded(0.05, ge=0.0, doc="... and deg per m")
    gate_chi2: float = bounded(16.27, gt=0.0, doc="... beyond this chi^2 (3 degrees of freedom; 16.27: 99.9 %)")
    gate_chain: bool = _doc(
        False,
        "those checks take what the scan matches between nearby nodes know of the path (their covariance "
        "propagated along them, large along a bare corridor, small where scans pinned it) instead of path_drift "
        "per metre (off: on random buildings it refused the loops that undid a humanoid's slips, 3 walks of 50)",
    )
    check_agreement: bool = _doc(
        True, "keep the filter's answer (and say so) when the map agrees less with the back end's than without it"
    )
    loss: RobustLoss = _doc(
        RobustLoss.CAUCHY,
        "gnc: graduated non-convexity (truncated least squares: loops that disagree weigh nothing); cauchy; huber",
    )
    loss_scale: float = bounded(3.0, gt=0.0, doc="the loss's scale, in standard deviations of a loop edge")


@dataclass(frozen=True)
class SlamConfig:
    particles: int = bounded(
        0, lo=0, hi=MAX_PARTICLES, doc="0: per filter (100 single-map, 30 rbpf: each particle carries a map)"
    )
    seed: int = bounded(0, lo=0)
    every: int = bounded(1, lo=1)  # process every k-th scan
    resample_threshold: float = bounded(0.5, ge=0.0, le=1.0)  # resample when N_eff < threshold * N
    resample_method: ResampleMethod = ResampleMethod.SYSTEMATIC
    estimate: PoseEstimate = PoseEstimate.MEAN
    map: MapConfig = field(default_factory=MapConfig)
    motion: MotionConfig = field(default_factory=MotionConfig)
    sensor: SensorConfig = field(default_factory=SensorConfig)
    local_search: LocalSearchConfig = field(default_factory=LocalSearchConfig)
    filter: SlamFilter = _doc(SlamFilter.AUTO, "auto: rbpf (single when local_search is enabled), or single, rbpf")
    rbpf: RbpfConfig = field(default_factory=RbpfConfig)
    backend: Backend = _doc(
        Backend.GRAPH, "graph: close loops with a pose graph behind the filter; none: the filter alone"
    )
    graph: GraphConfig = field(default_factory=GraphConfig)

    def __post_init__(self) -> None:
        check_config(self)  # the sections' fields too, named section.key


# Older messages naming several of LocalizerConfig's fields, raised for any of them.
_KLD = "kld_err must be in (0, 1) and kld_z in (0.5, 1)"
_POSITIVE = "sigma_hit, beam_temperature and max_dist must be positive"
_Z = "z_hit must be in (0, 1] and z_rand in [0, 1)"
_ODOMETRY = "alpha1..alpha5, k_left and k_right must not be negative, axle must be positive"
_RECOVERY_RATES = "need 0 < recovery_alpha_slow < recovery_alpha_fast <= 1"


@dataclass(frozen=True)
class LocalizerConfig:
    """Settings of :class:`~pfslam.filters.localize.Localizer`.

    Names follow AMCL where it has the setting; each field's note (printed by
    ``pfslam dump-config``) gives AMCL's name where it differs. As in ROS, angles in a
    file are radians (``update_min_a``, ``kld_bin_a``, ``initial_std_theta``); the command
    line's are degrees. Files written before the radian keys may still hold
    ``update_min_a_deg`` and ``kld_bin_deg``: they are read as degrees and converted (see
    :data:`DEGREE_KEYS`). Choices that differ from AMCL:

    * ``beam_temperature``: log-weight += sum of the beams' log p / beam_temperature. Beams
      of one scan are far from independent (neighbours see the same wall), so the plain
      product makes the weights over-confident and the cloud collapses; 10 keeps ~60 beams
      about as sharp as 6 independent ones.
    * ``update_min_d`` / ``update_min_a`` 0.05 m / 3 deg instead of 0.2 m / 30 deg:
      at 10-40 Hz scans AMCL's values would leave the cloud to odometry for seconds.
    * ``min_particles`` 500 (AMCL 100): slightly more accurate on the simulated office
      log (0.037 vs 0.042 m RMSE over 4 seeds) at little cost; 100 also tracks.
    * ``global_particles`` / ``global_density``: a global initialisation spreads
      ``global_density`` particles per m2 of free space (at least ``global_particles``, at
      most 2,000,000) over the map; the first resampling cuts them to the KLD count. A
      density, not a count, because what matters is how many first guesses fall close
      enough to the robot (0.1 m, a few degrees) to fit its scan: with a fixed 50,000 on a
      600 m2 office floor, 2 of 10 simulated walks locked onto a look-alike corridor for
      15-30 s; at 300 per m2 none did.
    * ``global_start`` bnb: a global start matches its first scan over the whole map and
      every heading by branch and bound (see :mod:`~pfslam.filters.globalstart`) and seeds
      the particles round every place scoring 0.75 of the best (48 at most), each kept as a
      mode with 200 particles at least until one has won (``Localizer.ambiguous`` till then).
      AMCL spreads them uniformly, as ``uniform`` does. On the 80 rough 200-s walks at
      odometry 0.9-1.1x (bench/localize/global_start.py) the estimate stays within 0.3 m
      from 1 s after the first motion on all 80 (uniform: 55; found at most 0.4 s after it,
      uniform 9.7 s), and from 1 s after the first scan on 60 (uniform: 23): the others
      stand 5 s seeing 2 m of a corridor corner that fits 15 places, and say so; Intel is
      found at its first scan either way. In the aliasing worlds (twins, rooms, pillars,
      seeds 0-9) no run stopped being ambiguous while more than 0.3 m off.
    * ``odom_model`` omni (AMCL's default is diff): a walking robot sways sideways, which
      the diff model reads as two opposite turns and answers with alpha4 x those turns of
      translation noise (17 cm on a 1.25 cm step of a 6 cm sway).
    * ``sigma_hit_adapt`` (on) fits the field's width, from 0.2 m down to 0.1 m or up to
      0.3 m, to the end points' distances from the walls while settled: 1.5 x the scale of
      their half-normal, from their median. AMCL's fixed 0.2 m is wide for a map whose walls
      agree with the scans to a few centimetres: the cloud's mean then sits where the
      likelihood falls off most slowly, further along the beams, and Intel's localization
      ran 4.3 cm ahead of the map's own run (0.065 m against it; fitted, 0.046 m); the
      rough simulated walks with odometry 3 % short had a 99th percentile of 0.066 m
      (fitted, 0.045 m). The Mines rover's blurred map keeps it near 0.12 m (0.072-0.091
      against 0.073-0.082 m at 0.2 m, seeds 0-3). The recovery measures its fit with the
      configured width, so narrowing is not read as a worse fit. An earlier fit, from the
      distances within 3 x the present width, narrowed itself (its gate narrowed with it) and
      lost the Mines rover (1.0 m).
    * ``recovery_candidates`` 100: each injected particle is the pick by weight of 100
      guesses over free space. The guesses must find a robot that the cloud lost, or never
      had (a global start that settled at a look-alike place): one in about 100,000 lands
      within 0.2 m and 5 deg of it on a 600 m2 floor. With 10, 3-4 of 160 global starts on
      rough walks (odometry 0.9-1.1x, two filter seeds) settled at a look-alike place and
      stayed there for 10-35 s, while the true pose fitted the scans far better (per beam
      log p -0.05 against -0.2); with 100, none did, at the same cost (a recovery is rare),
      Intel's localization 8 % slower and as accurate, the Mines rover 0.064-0.074 m
      against 0.072-0.091 m.
    * ``odom_scale_adapt`` (on): the odometry's translation and rotation scales are learnt
      from the filter's own corrections while it is settled (see
      :class:`~pfslam.filters.odometry_scale.OdometryScale`) and divided out. A likelihood field
      hardly pins the position along a corridor, so behind odometry that reads 4 % long the
      estimate ran 4-5 cm ahead of the robot (simulated walks, 4 % long: RMSE 0.054-0.062 ->
      0.032-0.035 m, mean along-track error 0.042-0.050 -> 0.007-0.012 m; rough walks
      0.040-0.057 -> 0.030-0.034 m; Intel map-then-localize aligned 0.087 -> 0.076 m).
    * ``odom_scale_spread`` 0.1: after a global start the translation scale is not
      learnt only once the cloud settles but carried by each particle, drawn uniformly
      within 1 -+ 0.1 at the start (and for injected particles), resampled with the
      particles and drifting slowly (see :data:`~pfslam.filters.odometry_scale.SCALE_DRIFT`): the
      particles that fit are those whose scale is right, from the first update on (rough
      walks, odometry 0.9x: the slowest settle 51.7 -> 17.6 s). From a known start it is off.
    * ``interpolate`` (on): the field is read bilinearly between cell centres, so the
      weights change smoothly with sub-cell moves (Mines rover against its SLAM run 0.081 ->
      0.073 m with the scale learnt, 0.083 m without interpolation).
    * ``recovery_ratio`` 0.95 (AMCL: 1): random particles only once the short-term
      likelihood is 5 % below the long-term one; at 1 the jitter of a filter that is not
      lost (1st percentile 0.993) injected particles at half of all updates.
    * ``initial_std_*`` are standard deviations; AMCL's ``initial_cov_xx/yy/aa`` are their squares.
    """

    particles: int = bounded(500, lo=1, hi=MAX_PARTICLES, doc="initial count (the fixed count with kld off)")
    min_particles: int = bounded(500, lo=1, hi=MAX_PARTICLES, doc="KLD-sampling's lower bound (AMCL min_particles)")
    max_particles: int = bounded(5000, lo=1, hi=MAX_PARTICLES, doc="KLD-sampling's upper bound (AMCL max_particles)")
    global_start: GlobalStart = _doc(
        GlobalStart.BNB,
        "bnb: a global start matches its first scan over the whole map and every heading and puts the "
        "particles at the best few places; uniform: particles uniform over free space (global_density)",
    )
    global_particles: int = bounded(
        50000, lo=1, hi=MAX_PARTICLES, doc="at least this many particles for a uniform global start (--global)"
    )
    global_density: float = bounded(
        300.0, ge=0.0, le=1e5, doc="particles per m2 of free space for a global start (at most 2,000,000)"
    )
    kld: bool = _doc(True, "KLD-sampling adapts the particle count")
    kld_err: float = bounded(
        0.05,
        gt=0.0,
        lt=1.0,
        error=_KLD,
        doc="KLD bound: largest error between true and estimated distribution (AMCL kld_err)",
    )
    kld_z: float = bounded(
        0.99, gt=0.5, lt=1.0, error=_KLD, doc="KLD bound: upper quantile probability (AMCL kld_z 0.99)"
    )
    kld_bin_xy: float = bounded(0.5, gt=0.0, what="a distance in metres", doc="m, KLD histogram bin size in x and y")
    kld_bin_a: float = bounded(
        math.radians(10.0),
        gt=0.0,
        le=2 * math.pi,
        what="an angle in radians",
        doc="rad, KLD histogram bin size in heading (10 deg; older files: kld_bin_deg in degrees)",
    )
    beams: int = bounded(
        60,
        lo=1,
        error="particles and beams must be at least 1",
        doc="end points used per update, evenly subsampled (AMCL laser_max_beams)",
    )
    laser_min_range: float = _doc(
        -1.0, "m, readings at or below are no returns; -1: the sensor's own (AMCL laser_min_range)"
    )
    laser_max_range: float = _doc(
        -1.0,
        "m, readings at or beyond are no returns, and the range of the beam "
        "model and z_rand; -1: the sensor's own (the models' range at most 30 m) "
        "(AMCL laser_max_range)",
    )
    model: SensorModel = _doc(SensorModel.LIKELIHOOD_FIELD, "likelihood_field or beam (AMCL laser_model_type)")
    z_short: float = bounded(
        0.1, ge=0.0, le=1.0, doc="beam model: unexpected obstacles, exponential with lambda_short (AMCL laser_z_short)"
    )
    lambda_short: float = bounded(0.5, gt=0.0, doc="beam model (AMCL laser_lambda_short)")
    sigma_hit: float = bounded(
        0.2, gt=0.0, error=_POSITIVE, doc="m (AMCL laser_sigma_hit); where the field starts with sigma_hit_adapt"
    )
    sigma_hit_adapt: bool = _doc(
        True,
        "fit the width, within 0.5-1.5 x sigma_hit, to how far the end points "
        "lie from the map's walls (their median), once settled",
    )
    z_hit: float = bounded(0.95, gt=0.0, le=1.0, error=_Z, doc="AMCL laser_z_hit")
    z_rand: float = bounded(0.05, ge=0.0, lt=1.0, error=_Z, doc="AMCL laser_z_rand")
    max_dist: float = bounded(
        2.0, gt=0.0, error=_POSITIVE, doc="m, distance cap of the likelihood field (AMCL laser_likelihood_max_dist)"
    )
    interpolate: bool = _doc(
        True, "read the likelihood field bilinearly between cell centres (sub-cell positions), not per cell"
    )
    beam_temperature: float = bounded(
        10.0, gt=0.0, error=_POSITIVE, doc="log-weight += sum(log p) / beam_temperature (beams are not independent)"
    )
    update_min_d: float = bounded(
        0.05, ge=0.0, what="a distance in metres", doc="m of travel before an update (AMCL update_min_d)"
    )
    update_min_a: float = bounded(
        math.radians(3.0),
        ge=0.0,
        what="an angle in radians",
        doc="rad of turn before an update (3 deg; AMCL update_min_a; older files: update_min_a_deg in degrees)",
    )
    resample_threshold: float = bounded(
        0.5, ge=0.0, le=1.0, error="resample_threshold must be in [0, 1]", doc="resample when N_eff < threshold * N"
    )
    resample_method: ResampleMethod = _doc(ResampleMethod.SYSTEMATIC, "systematic, stratified, multinomial or residual")
    alpha1: float = bounded(
        0.2, ge=0.0, error=_ODOMETRY, doc="odometry model: rotation noise from rotation (AMCL odom_alpha1)"
    )
    alpha2: float = bounded(
        0.2, ge=0.0, error=_ODOMETRY, doc="odometry model: rotation noise from translation (AMCL odom_alpha2)"
    )
    alpha3: float = bounded(
        0.2, ge=0.0, error=_ODOMETRY, doc="odometry model: translation noise from translation (AMCL odom_alpha3)"
    )
    alpha4: float = bounded(
        0.2, ge=0.0, error=_ODOMETRY, doc="odometry model: translation noise from rotation (AMCL odom_alpha4)"
    )
    alpha5: float = bounded(
        0.1,
        ge=0.0,
        error=_ODOMETRY,
        doc="omni model: translation noise across the travel from translation (AMCL odom_alpha5)",
    )
    odom_model: OdomModel = _doc(
        OdomModel.OMNI, "omni: noise from the net motion; diff: rot1, trans, rot2 (AMCL odom_model_type)"
    )
    axle: float = bounded(0.33, gt=0.0, error=_ODOMETRY, doc="m, differential drive (logs with wheel travel)")
    k_left: float = bounded(0.05, ge=0.0, error=_ODOMETRY, doc="differential drive: left wheel travel noise per metre")
    k_right: float = bounded(
        0.05, ge=0.0, error=_ODOMETRY, doc="differential drive: right wheel travel noise per metre"
    )
    odom_scale_adapt: bool = _doc(
        True,
        "estimate the odometry's translation and rotation scale from the filter's own corrections "
        "and divide the odometry by it",
    )
    odom_scale_window: float = bounded(
        20.0, gt=0.0, le=1e4, doc="m of travel (rad of turn for the rotation scale) the scale estimate forgets over"
    )
    odom_scale_bound: float = bounded(0.2, ge=0.0, le=0.5, doc="the scale estimates stay within 1 -+ this")
    odom_scale_spread: float = bounded(
        0.1,
        ge=0.0,
        le=0.5,
        doc="after a global start each particle carries its own translation scale, drawn within 1 -+ this "
        "and resampled with it; 0: one scale, learnt once the estimate has settled",
    )
    recovery: bool = _doc(True, "inject random particles when the recent likelihood falls below the long-term one")
    recovery_alpha_slow: float = bounded(
        0.001, gt=0.0, error=_RECOVERY_RATES, doc="long-term likelihood average's rate (AMCL recovery_alpha_slow)"
    )
    recovery_alpha_fast: float = bounded(
        0.1,
        gt=0.0,
        le=1.0,
        error=_RECOVERY_RATES,
        doc="short-term likelihood average's rate (AMCL recovery_alpha_fast)",
    )
    recovery_candidates: int = bounded(
        100, lo=1, hi=1000, doc="guesses over free space, weighed by the scan, per injected particle"
    )
    recovery_ratio: float = bounded(
        0.95, gt=0.0, le=1.0, doc="inject once the short-term average < ratio x the long-term one (AMCL: 1)"
    )
    health_tolerance: float = bounded(
        0.2,
        gt=0.0,
        doc="m: an end point this near a mapped wall is explained; a beam through a wall this far before its end contradicts the map",
    )
    health_tracking: float = bounded(
        0.5,
        ge=0.0,
        le=1.0,
        doc="health: the quality (median of 3 updates) tracking needs; below it the state is degraded",
    )
    health_lost: float = bounded(0.2, ge=0.0, le=1.0, doc="health: the state is lost while the quality is below this")
    ground_z: float = _doc(0.15, "m, points lower than this are floor hits, not walls")
    seed: int = bounded(0, lo=0, doc="random seed")
    initial_std_x: float = bounded(
        0.1,
        ge=0.0,
        doc="m, spread of the start around --initial-pose (AMCL initial_cov_xx is its square); --initial-std overrides",
    )
    initial_std_y: float = bounded(0.1, ge=0.0, doc="m (AMCL initial_cov_yy is its square)")
    initial_std_theta: float = bounded(math.radians(5.0), ge=0.0, doc="rad (5 deg; AMCL initial_cov_aa is its square)")

    def __post_init__(self) -> None:
        check_config(self)
        # Cross-field checks (the bounds of each field are declared on it).
        if not self.min_particles <= self.max_particles:
            raise ConfigError("need 1 <= min_particles <= max_particles")
        if not self.recovery_alpha_slow < self.recovery_alpha_fast:
            raise ConfigError(_RECOVERY_RATES)
        if not self.health_lost <= self.health_tracking:
            raise ConfigError("need 0 <= health_lost <= health_tracking <= 1")
        # The laser ranges: negative is the sensor's own (AMCL's -1); zero would make every
        # reading a no return; a maximum given must lie above the minimum.
        if self.laser_max_range == 0:
            raise ConfigError("laser_max_range must be a distance in metres > 0, or -1 for the sensor's own, not 0")
        if 0 <= self.laser_max_range <= self.laser_min_range:
            raise ConfigError(
                f"laser_min_range ({self.laser_min_range:g}) must be below laser_max_range ({self.laser_max_range:g})"
            )

    @property
    def initial_std(self) -> tuple[float, float, float]:
        """The start's spread (x m, y m, theta rad)."""
        return (self.initial_std_x, self.initial_std_y, self.initial_std_theta)


@dataclass(frozen=True)
class CalibrationConfig:
    max_pairs: int = bounded(400, lo=1)  # scan pairs matched (evenly spread over the log)
    # Pairs are scans i and i + gap. Over one scan the odometry's own noise (encoder
    # quantisation, time stamp jitter) is a large part of the increment, which biases a
    # least-squares slope towards zero; three scans apart it is a third as large.
    gap: int = bounded(3, lo=1)
    max_points: int = bounded(300, lo=1)  # hits used per scan
    max_reach: float = bounded(10.0, gt=0.0)  # m, hits farther than this are not used
    resolution: float = bounded(0.02, gt=0.0)  # m, cell size of the matching grid
    sigma_coarse: float = bounded(0.1, gt=0.0)  # m, width of the smoothed wall map in the coarse search
    sigma_fine: float = bounded(0.04, gt=0.0)  # m, ... in the fine searches
    min_overlap: float = bounded(0.3, ge=0.0, le=1.0)  # mean fine-map value a match needs to be kept
    max_latency: float = bounded(0.3, ge=0.0, le=5.0)  # s, latencies -max..max are tried
    latency_step: float = bounded(0.005, gt=0.0)  # s
    min_pairs: int = bounded(20, lo=1)  # fewer usable pairs than this is an error

    def __post_init__(self) -> None:
        check_config(self)
