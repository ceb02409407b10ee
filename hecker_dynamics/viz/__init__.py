"""Pictures of scenes and bags: animations and stills (:mod:`.render`), one frame
(:mod:`.draw`), plots against time (:mod:`.plot`), progress bars (:mod:`.progress`).

Importing this package imports no matplotlib: :mod:`.frames` reads runs and bags without
it; :mod:`.draw`, :mod:`.render` and :mod:`.plot` need the ``viz`` extra
(``pip install hecker_dynamics[viz]``).
"""
from .frames import Arrow, BodyPose, Frame, Timeline, VizError, bag_timeline, run_timeline

__all__ = ["Arrow", "BodyPose", "Frame", "Timeline", "VizError", "bag_timeline",
           "run_timeline"]
