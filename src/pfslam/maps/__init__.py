"""Maps: the occupancy grid (:mod:`~pfslam.maps.grid`: log-odds cells, growth, the ray
update, ROS ``map_server`` files), the Rao-Blackwellized filter's tiled copy-on-write maps
(:mod:`~pfslam.maps.tiled`) and distance fields over walls (:mod:`~pfslam.maps.fields`).

May import: kernels, config, errors, geometry, frames, sensor. Never a filter, a loader, a view.
"""
