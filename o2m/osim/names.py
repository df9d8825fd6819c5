"""MuJoCo joint names of OpenSim coordinates (one rule for the converter, validation and replay).

OpenSim addresses a coordinate by path, ``/jointset/<joint>/<coordinate>``, so two joints may each own a
coordinate of the same name. MuJoCo names must be unique and o2m names each MuJoCo joint after its
coordinate, so a name shared by several joints becomes ``<joint>_<coordinate>`` for each of them; a name
unique in the model is kept. This module does not import ``opensim``: callers pass plain names.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable


class CoordinateNames:
    """The MuJoCo name of every coordinate of a model, and the lookup of OpenSim references to them.

    ``owners`` lists (joint name, coordinate name) in the model's coordinate-set order (joint by joint).
    """

    def __init__(self, owners: Iterable[tuple[str, str]]):
        self.owners = list(owners)
        counts = Counter(c for _, c in self.owners)
        self.shared = {c for c, n in counts.items() if n > 1}
        self.by_owner: dict[tuple[str, str], str] = {}
        self.first: dict[str, str] = {}
        for joint, coord in self.owners:
            name = f"{joint}_{coord}" if coord in self.shared else coord
            if name in self.by_owner.values() or (coord in self.shared and name in counts):
                raise ValueError(f"coordinate '{coord}' of joint '{joint}' would be renamed '{name}', "
                                 "which another coordinate already uses")
            self.by_owner[(joint, coord)] = name
            self.first.setdefault(coord, name)  # OpenSim's CoordinateSet.get(name) returns the first match

    def __call__(self, joint: str, coord: str) -> str:
        """The MuJoCo joint name of coordinate ``coord`` of OpenSim joint ``joint``."""
        return self.by_owner.get((joint, coord), coord)

    def resolve(self, ref: str) -> str:
        """The MuJoCo name for an OpenSim reference: a bare coordinate name or a path ending ``joint/coord``.

        A bare shared name means the first coordinate of that name in the coordinate set, as OpenSim
        resolves it; unknown references come back unchanged (callers report them).
        """
        parts = [p for p in ref.strip().split("/") if p]
        if len(parts) >= 2 and (parts[-2], parts[-1]) in self.by_owner:
            return self.by_owner[(parts[-2], parts[-1])]
        return self.first.get(parts[-1], ref.strip()) if parts else ref.strip()

    def renamed(self) -> list[tuple[str, str, str]]:
        """(joint, coordinate, MuJoCo name) of every coordinate whose name had to change."""
        return [(j, c, n) for (j, c), n in self.by_owner.items() if n != c]


def opensim_coordinate_names(os_model) -> dict[str, str]:
    """Absolute path of every coordinate of a loaded OpenSim model -> its MuJoCo joint name."""
    cs = os_model.getCoordinateSet()
    coords = [cs.get(i) for i in range(cs.getSize())]
    names = CoordinateNames((c.getJoint().getName(), c.getName()) for c in coords)
    return {c.getAbsolutePathString(): names(c.getJoint().getName(), c.getName()) for c in coords}


def opensim_coordinate(os_model, name: str):
    """The coordinate of a loaded OpenSim model whose MuJoCo joint name is ``name`` (KeyError if none)."""
    table = opensim_coordinate_names(os_model)
    cs = os_model.getCoordinateSet()
    for i in range(cs.getSize()):
        if table[cs.get(i).getAbsolutePathString()] == name:
            return cs.get(i)
    raise KeyError(f"no coordinate of {os_model.getName()} is MuJoCo joint {name!r}")
