"""Evaluation: trajectory errors (ATE raw and SE(2)-aligned, RPE), the SLAM benchmark's
relations metric and the map agreement that needs no ground truth
(:mod:`~pfslam.eval.metrics`). Plain functions, no printing.

May import: maps, sensor, frames, geometry, config, errors. Never a filter or a view.
"""
