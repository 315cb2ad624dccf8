"""pfslam: 2D LIDAR particle-filter SLAM and Monte Carlo localization."""

__version__ = "0.1.0"
