"""o2m: convert OpenSim models to MuJoCo and measure their fidelity against OpenSim 4.6.

The layout is the design: :mod:`o2m.osim` reads OpenSim (the only place that imports it),
:mod:`o2m.mj` poses and simulates MuJoCo models, :mod:`o2m.convert` writes MJCF,
:mod:`o2m.validate` compares, :mod:`o2m.paper` is the paper's experiment and :mod:`o2m.viz`
shows. ``convert`` and ``validate`` never import each other.

``from o2m.convert import convert`` converts a model (``o2m.convert`` is the subpackage, so a
function of that name cannot live at the top); :func:`compare_kinematics` and
:func:`compare_muscles` measure it against OpenSim.
"""

from o2m.convert import ConvertOptions
from o2m.errors import O2MError
from o2m.validate import compare_kinematics, compare_muscles

__version__ = "0.1.0"

__all__ = ["ConvertOptions", "O2MError", "__version__", "compare_kinematics", "compare_muscles"]
