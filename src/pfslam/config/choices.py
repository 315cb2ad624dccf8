"""The modes a setting chooses among (Enums whose values are the strings written in files)."""

from __future__ import annotations

from enum import StrEnum


class Choice(StrEnum):
    """A mode: equal to its value (a string), which is what files hold."""


class ResampleMethod(Choice):
    SYSTEMATIC = "systematic"
    STRATIFIED = "stratified"
    MULTINOMIAL = "multinomial"
    RESIDUAL = "residual"


class ParticleWeight(Choice):
    PEAK = "peak"  # the likelihood of the scan at the particle's match
    NORMALISER = "normaliser"  # that times the integral of the match's Gaussian under the odometry's


class PoseEstimate(Choice):
    MEAN = "mean"  # weighted mean, circular mean for theta
    BEST = "best"  # the heaviest particle


class ScoringMap(Choice):
    CELLS = "cells"  # the map's cell values (sharp; best when scans are dense, e.g. 40 Hz)
    FIELD = "field"  # a smoothed wall map exp(-d^2 / 2 sigma^2) (a wide basin, for big steps)
    AUTO = "auto"  # "field" after big steps, "cells" otherwise


class Backend(Choice):
    GRAPH = "graph"
    NONE = "none"


class RobustLoss(Choice):
    GNC = "gnc"
    CAUCHY = "cauchy"
    HUBER = "huber"


class SlamFilter(Choice):
    AUTO = "auto"  # per log kind (see resolve_filter): rbpf, single when the local search is asked for
    SINGLE = "single"  # one map updated from the estimate (the course's method)
    RBPF = "rbpf"  # Rao-Blackwellized: a map per particle, scan-matched proposal (GMapping's family)


class SensorModel(Choice):
    LIKELIHOOD_FIELD = "likelihood_field"
    BEAM = "beam"  # ray cast per beam; slower, for comparison


class OdomModel(Choice):
    OMNI = "omni"  # noise from the net motion (sideways steps are not turns)
    DIFF = "diff"  # AMCL's differential model: rot1, trans, rot2


class GlobalStart(Choice):
    BNB = "bnb"  # the first scan matched over the whole map (branch and bound), particles at its best places
    UNIFORM = "uniform"  # particles uniform over free space, left to converge
