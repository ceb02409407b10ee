"""Sensors a scene mounts on its bodies (``sensors.<name>``): laser scanners that cast rays
against walls and shapes (:mod:`.laser`) and inertial measurement units read from the
dynamics (:mod:`.imu`). Pure numpy, no ROS import; the node publishes their readings."""
