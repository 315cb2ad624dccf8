"""Tools around the filters: the THOR-format simulator with ground truth
(:mod:`~pfslam.tools.simulate`; its walk :mod:`~pfslam.tools.walk` and what it shares with the
wheeled robots of :mod:`~pfslam.tools.wheeled` :mod:`~pfslam.tools.simcommon`), log conversion to ROS bags and CARMEN
(:mod:`~pfslam.tools.convert`) and the odometry calibration from the scans
(:mod:`~pfslam.tools.calibrate`).

May import: io, maps, kernels, sensor, motion, config, frames, geometry, errors. Never a
filter, a view, the pipeline or the CLI.
"""
