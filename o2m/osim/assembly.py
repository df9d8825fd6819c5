"""OpenSim's assembled default state: the coordinate values ``initSystem`` leaves once its
assembler has satisfied the model's constraints.

A coordinate's ``default_value`` need not satisfy a PointConstraint, WeldConstraint or the like;
OpenSim's ``initSystem`` then moves the coordinates free to move until the constraints hold, and
a simulation starts there. :func:`assembled_defaults` reads those values, named as the MuJoCo
joints (:mod:`o2m.osim.names`), for the converter's ``default-pose`` keyframe. Radians or metres.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from o2m.osim import runtime
from o2m.osim.names import opensim_coordinate_names

__all__ = ["AssembledCoordinate", "assembled_defaults"]


@dataclass(frozen=True)
class AssembledCoordinate:
    """One coordinate of the default state: its MuJoCo joint ``name``, its ``default_value`` and
    the ``value`` OpenSim's assembly left (rad or m); ``dependent`` when a constraint sets it."""

    name: str
    default_value: float
    value: float
    dependent: bool

    @property
    def moved(self) -> float:
        """How far the assembly moved the coordinate from its default value (rad or m)."""
        return self.value - self.default_value


def assembled_defaults(osim_path: str | os.PathLike) -> list[AssembledCoordinate]:
    """Every coordinate of the model at ``osim_path`` that OpenSim neither holds (locked,
    prescribed) nor sets from a CoordinateCouplerConstraint, in the state ``initSystem`` returns
    (the file's assembly accuracy). A coupler's dependent is left out: the converted model's
    joint equality gives it from its independents. Raises ModelFileError where OpenSim cannot
    load the model."""
    osim = runtime.opensim()
    model, state = runtime.load_model(osim_path)
    model.realizePosition(state)
    coupled = set()
    cons = model.getConstraintSet()
    for i in range(cons.getSize()):
        cc = osim.CoordinateCouplerConstraint.safeDownCast(cons.get(i))
        if cc is not None and cc.isEnforced(state):
            coupled.add(cc.getDependentCoordinateName())
    names = opensim_coordinate_names(model)
    cs = model.getCoordinateSet()
    out = []
    for c in (cs.get(i) for i in range(cs.getSize())):
        if runtime.is_held(c, state) or c.getName() in coupled:
            continue
        out.append(AssembledCoordinate(names[c.getAbsolutePathString()], float(c.getDefaultValue()),
                                       float(c.getValue(state)), bool(c.isDependent(state))))
    return out
