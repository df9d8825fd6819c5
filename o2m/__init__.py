"""o2m: convert OpenSim models to MuJoCo and measure their fidelity against OpenSim 4.6.

The layout is the design: :mod:`o2m.osim` reads OpenSim (the only place that imports it),
:mod:`o2m.mj` poses and simulates MuJoCo models, :mod:`o2m.convert` writes MJCF,
:mod:`o2m.validate` compares, :mod:`o2m.paper` is the paper's experiment and :mod:`o2m.viz`
shows. ``convert`` and ``validate`` never import each other.

``from o2m.convert import convert`` converts a model (``o2m.convert`` is the subpackage, so a
function of that name cannot live at the top); :func:`compare_kinematics` and
:func:`compare_muscles` measure it against OpenSim. They load on first use, so that importing
one part of o2m (an OpenSim worker process, say) does not import the others.
"""

from o2m.errors import O2MError

__version__ = "0.1.0"

__all__ = ["ConvertOptions", "O2MError", "__version__", "compare_kinematics", "compare_muscles"]


def __getattr__(name: str):
    if name in ("compare_kinematics", "compare_muscles"):
        from o2m import validate

        return getattr(validate, name)
    if name == "ConvertOptions":
        from o2m.convert import ConvertOptions

        return ConvertOptions
    raise AttributeError(f"module 'o2m' has no attribute {name!r}")
