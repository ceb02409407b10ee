"""Drives a scene mounts on its bodies (``drives.<name>``): controllers that turn velocity
commands into forces at points (:mod:`.diff_drive`), and the loop that runs them with a
simulation (:mod:`.control`). Pure Python and numpy, no ROS import."""
