"""suds_ros: online identification of shape-underactuated dissipative systems.

The core (:mod:`suds_ros.core`, :mod:`suds_ros.io`) needs only numpy, scipy and
mcap; the ROS 2 adapters live in :mod:`suds_ros.ros`.
"""

__version__ = "0.1.0"
