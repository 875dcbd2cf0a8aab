"""Headless rerun recordings (``.rrd``) of true versus estimated signals, for review.

- :mod:`~hgo_mj.record.layout`: entity paths, series styles and the default blueprint (pure);
- :mod:`~hgo_mj.record.documents`: the ``/scenario`` and ``/metrics`` text documents;
- :mod:`~hgo_mj.record.poses`: the MuJoCo geometry and its poses (``mj_kinematics``'s steps
  in numpy);
- :mod:`~hgo_mj.record.recorder`: :class:`Recorder`, on rerun's public API;
- :mod:`~hgo_mj.record.read`: :func:`read`, a recording's series as a pandas DataFrame.
"""

from .layout import EPISODE, SIM_TIME, STEP, diagnostic_path, observer_color
from .poses import Poses
from .read import read
from .recorder import Recorder, record_trajectory

__all__ = ["EPISODE", "SIM_TIME", "STEP", "Poses", "Recorder", "diagnostic_path",
           "observer_color", "read", "record_trajectory"]
