"""rosbag2 bags without ROS: reading and writing (``io``), replaying a scene against a
bag's inputs (``replay``) and comparing bags (``compare``)."""
from .compare import compare_bags, compare_contents
from .io import BagContents, BagError, BagWriter, read_bag
from .replay import ReplayError, replay, replay_to_bag, script_to_bag

__all__ = ["compare_bags", "compare_contents", "BagContents", "BagError", "BagWriter",
           "read_bag", "ReplayError", "replay", "replay_to_bag", "script_to_bag"]
