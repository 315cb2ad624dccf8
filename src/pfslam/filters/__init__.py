"""The filters, behind one interface (:class:`~pfslam.filters.base.Filter`):

- :mod:`~pfslam.filters.single`: SLAM with one map updated from the estimate;
- :mod:`~pfslam.filters.localize`: Monte Carlo localization on a known map;
- :mod:`~pfslam.filters.predict`: the prediction step they share.
"""

from pfslam.filters.base import Filter
from pfslam.filters.localize import Localizer
from pfslam.filters.rbpf import RaoBlackwellizedSlam
from pfslam.filters.single import SingleMapSlam

__all__ = ["Filter", "Localizer", "RaoBlackwellizedSlam", "SingleMapSlam"]
