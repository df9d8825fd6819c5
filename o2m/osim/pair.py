"""An OpenSim model beside its MuJoCo conversion, loaded once and matched name by name.

:class:`ModelPair` is what both the converter's fits and the validators work from: the
independent coordinates (neither locked nor dependent) and their MuJoCo joints, the path forces
and their MuJoCo tendons, OpenSim states at given coordinate values, and lengths in both models.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np

from o2m.errors import MissingJointError
from o2m.mj.posing import joint_equality_plan, joint_qpos_address, load_mjcf
from o2m.mj.tendons import mujoco_tendon_lengths
from o2m.osim import runtime
from o2m.osim.couplers import coupler_chain, set_coupled
from o2m.osim.names import opensim_coordinate_names

__all__ = ["HELD", "ModelPair", "is_actuator", "path_forces"]

#: A pose whose constraints hold within this (m or rad, OpenSim's default assembly accuracy) once
#: its couplers are set is not given to OpenSim's assembler (:meth:`ModelPair.os_state`).
HELD = 1e-9


def path_forces(os_model: Any) -> list[tuple[str, str, Any]]:
    """(name, concrete class, downcast object) of every path force: PathActuators (muscles
    included), Ligaments and PathSprings."""
    out = []
    fs = os_model.getForceSet()
    for i in range(fs.getSize()):
        f = fs.get(i)
        obj = runtime.path_force(f)
        if obj is not None:
            out.append((f.getName(), f.getConcreteClassName(), obj))
    return out


def is_actuator(obj: Any) -> bool:
    """Whether an OpenSim path force is an actuator (a PathActuator, muscles included)."""
    return runtime.opensim().PathActuator.safeDownCast(obj) is not None


class ModelPair:
    """An OpenSim model and its MuJoCo twin, loaded and matched (coordinates, path forces)."""

    def __init__(self, osim_path: str | os.PathLike, mjcf_path: str | os.PathLike,
                 assembly_accuracy: float | None = 1e-12):
        opensim = runtime.opensim()

        self.osim_path, self.mjcf_path = os.fspath(osim_path), os.fspath(mjcf_path)
        self.os_model, self.init_state = runtime.load_model(self.osim_path, assembly_accuracy)
        self.mj_model = load_mjcf(self.mjcf_path)
        self.mj_data = mujoco.MjData(self.mj_model)
        self.plan = joint_equality_plan(self.mj_model)
        self.opensim = opensim

        self.mj_names = opensim_coordinate_names(self.os_model)
        cs = self.os_model.getCoordinateSet()
        self.coords = [cs.get(i) for i in range(cs.getSize())]
        st = self.init_state
        self.locked = [self.name(c) for c in self.coords if runtime.is_held(c, st)]
        self.dependent = [self.name(c) for c in self.coords if not runtime.is_held(c, st) and c.isDependent(st)]
        skip = set(self.locked) | set(self.dependent)
        self.indep = [c for c in self.coords if self.name(c) not in skip]
        self.indep_names = [self.name(c) for c in self.indep]
        missing = []
        for name in self.indep_names:
            try:
                joint_qpos_address(self.mj_model, name)
            except KeyError:
                missing.append(name)
        if missing:
            raise MissingJointError(missing, self.mjcf_path)
        self.defaults = {self.name(c): float(c.getValue(st)) for c in self.indep}

        self.forces = path_forces(self.os_model)
        m = self.mj_model
        tendon_names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_TENDON, i) or f"<tendon {i}>"
                        for i in range(m.ntendon)]
        self.tendon_names = tendon_names
        tid = {n: i for i, n in enumerate(tendon_names)}
        self.matched = [(n, k, obj) for n, k, obj in self.forces if n in tid]
        self.tendon_ids = np.array([tid[n] for n, _, _ in self.matched], dtype=int)
        self.missing_tendons = [n for n, _, _ in self.forces if n not in tid]
        os_names = {n for n, _, _ in self.forces}
        self.extra_tendons = [n for n in tendon_names if n not in os_names]
        self._spans: dict[str, set[str]] | None = None
        self.couplers = coupler_chain(self.os_model, self.init_state)
        # with another constraint too: the couplers alone, and the clamped ranges the assembler keeps
        self._partial = coupler_chain(self.os_model, st, partial=True) if self.couplers is None else None
        self._clamped = [(c, *sorted((c.getRangeMin(), c.getRangeMax()))) for c in self.indep if c.getClamped(st)]

    # -- OpenSim ------------------------------------------------------------------------
    def name(self, c: Any) -> str:
        """The MuJoCo joint name of OpenSim coordinate ``c`` (see :mod:`o2m.osim.names`)."""
        return self.mj_names[c.getAbsolutePathString()]

    def os_state(self, values: Mapping[str, float] | None, assemble: bool = True) -> Any:
        """A realised OpenSim state: init_state when ``values`` is None, else a copy with the
        given independent coordinates set and the constraints satisfied: the dependent
        coordinates set from their couplers where those are the only constraints
        (:mod:`o2m.osim.couplers`), else assembled (when ``assemble``, or when some coordinate is
        dependent; :meth:`_assembled`). Raises on assembly failure."""
        if values is None:
            state = self.init_state
        else:
            state = self.opensim.State(self.init_state)
            for c, n in zip(self.indep, self.indep_names, strict=True):
                if n in values:
                    c.setValue(state, float(values[n]), False)
            if self.couplers is not None:
                set_coupled(self.couplers, state)
            elif assemble or self.dependent:
                state = self._assembled(state)
        self.os_model.realizePosition(state)
        return state

    def _assembled(self, state: Any) -> Any:
        """``state`` (independent coordinates set) with every constraint satisfied. Where setting
        the couplers alone meets the others within :data:`HELD` and leaves every clamped
        coordinate in its range (a step of a coordinate no other constraint involves, from an
        assembled pose: about half of a wrap fit's finite differences on the neck-and-shoulder
        model), that state, without the assembler: the pose the assembler would keep (moment
        arms within 1e-6 mm of its), at ~2 ms instead of ~30-70 (its 1e-13 tolerance fails and
        relaxes at a third of its assemblies there). Else OpenSim's assembler, from ``state``
        as given."""
        if self._partial is not None and all(lo <= c.getValue(state) <= hi for c, lo, hi in self._clamped):
            trial = self.opensim.State(state)
            set_coupled(self._partial, trial)
            self.os_model.realizePosition(trial)
            if trial.getNQErr() == 0 or np.abs(trial.getQErr().to_numpy()).max() <= HELD:
                return trial
        # a fresh assembly solver: where one assembly fails, OpenSim's Model::assemble relaxes the
        # constraints (weight 20) for good, after which an assembled coordinate moves 1/21 of its
        # step (Rajagopal2016's knee after a pose just below its clamped range: every later
        # -dL/dq about it 21 times too small)
        self.os_model.updateAssemblyConditions(state)
        self.os_model.assemble(state)
        return state

    def os_indep_values(self, state: Any) -> dict[str, float]:
        return {n: float(c.getValue(state)) for c, n in zip(self.indep, self.indep_names, strict=True)}

    def os_lengths(self, state: Any) -> np.ndarray:
        return np.array([obj.getLength(state) for _, _, obj in self.matched], dtype=float)

    def coord(self, name: str) -> Any:
        for c in self.indep:
            if self.name(c) == name:
                return c
        raise KeyError(f"{name!r} is not an independent OpenSim coordinate of {self.osim_path}")

    def force(self, name: str) -> Any:
        for n, _, obj in self.matched:
            if n == name:
                return obj
        raise KeyError(f"{name!r} is not an OpenSim path force with a MuJoCo tendon of that name")

    # -- MuJoCo -------------------------------------------------------------------------
    def mj_lengths(self, values: Mapping[str, float]) -> np.ndarray:
        return mujoco_tendon_lengths(self.mj_model, self.mj_data, values, plan=self.plan)

    # -- structure ----------------------------------------------------------------------
    def dependent_drivers(self) -> dict[str, set[str]]:
        """Dependent coordinate -> the independent coordinates that move it (found by moving
        each independent coordinate to two values in its range and assembling)."""
        out: dict[str, set[str]] = {d: set() for d in self.dependent}
        if not self.dependent:
            return out
        dep = [c for c in self.coords if self.name(c) in out]
        ref = {self.name(c): float(c.getValue(self.init_state)) for c in dep}
        for c in self.indep:
            lo, hi = runtime.sample_bounds(c)
            for frac in (0.2, 0.8):
                try:
                    st = self.os_state({self.name(c): lo + frac * (hi - lo)})
                except Exception:
                    continue
                for d in dep:
                    if abs(float(d.getValue(st)) - ref[self.name(d)]) > 1e-10:
                        out[self.name(d)].add(self.name(c))
        return out

    def spanned(self) -> dict[str, set[str]]:
        """Muscle -> independent coordinates it spans in OpenSim: the coordinates of the joints
        connecting the bodies of its path points and wrap objects, those of its moving and
        conditional points, and the independent coordinates driving any of them (found once per
        pair: it assembles OpenSim at two values of each independent coordinate)."""
        if self._spans is None:
            self._spans = self._find_spans()
        return {name: set(coords) for name, coords in self._spans.items()}

    def _find_spans(self) -> dict[str, set[str]]:
        """:meth:`spanned`, found anew."""
        opensim = self.opensim
        parent: dict[str, tuple[Any, str]] = {}
        js = self.os_model.getJointSet()
        for i in range(js.getSize()):
            j = js.get(i)
            child = j.getChildFrame().findBaseFrame().getName()
            parent.setdefault(child, (j, j.getParentFrame().findBaseFrame().getName()))

        def chain(body: str) -> list[str]:
            out, seen = [], set()
            while body in parent and body not in seen:
                seen.add(body)
                j, body = parent[body]
                out.append(j.getName())
            return out

        joint_coords: dict[str, list[str]] = {}
        for i in range(js.getSize()):
            j = js.get(i)
            joint_coords[j.getName()] = [self.name(j.get_coordinates(k)) for k in range(j.numCoordinates())]
        drivers = self.dependent_drivers()
        indep = set(self.indep_names)

        def resolve(names: set[str]) -> set[str]:
            out = set()
            for n in names:
                if n in indep:
                    out.add(n)
                elif n in drivers:
                    out |= drivers[n]
            return out

        spans: dict[str, set[str]] = {}
        for name, _, obj in self.matched:
            try:
                gp = obj.getGeometryPath()
            except Exception:  # not a GeometryPath (e.g. FunctionBasedPath): check everything
                spans[name] = set(indep)
                continue
            bodies, coords = set(), set()
            pps = gp.getPathPointSet()
            for i in range(pps.getSize()):
                p = pps.get(i)
                bodies.add(p.getParentFrame().findBaseFrame().getName())
                mp = opensim.MovingPathPoint.safeDownCast(p)
                if mp is not None:
                    for has, get in ((mp.hasXCoordinate, mp.getXCoordinate), (mp.hasYCoordinate, mp.getYCoordinate),
                                     (mp.hasZCoordinate, mp.getZCoordinate)):
                        try:
                            if has():
                                coords.add(self.name(get()))
                        except Exception:
                            pass
                cp = opensim.ConditionalPathPoint.safeDownCast(p)
                if cp is not None:
                    try:
                        coords.add(self.name(cp.getCoordinate()))
                    except Exception:
                        pass
            ws = gp.getWrapSet()
            for i in range(ws.getSize()):
                try:
                    bodies.add(ws.get(i).getWrapObject().getFrame().findBaseFrame().getName())
                except Exception:
                    pass
            chains = [set(chain(b)) for b in bodies]
            joints = set().union(*chains) - set.intersection(*chains) if chains else set()
            for j in joints:
                coords.update(joint_coords.get(j, []))
            spans[name] = resolve(coords)
        return spans

    def sweep_values(self, coordinate: Any, step: float, linear_step: float) -> np.ndarray:
        lo, hi = runtime.sample_bounds(coordinate)
        s = linear_step if coordinate.getMotionType() == runtime.TRANSLATIONAL else step
        n = max(int(math.ceil((hi - lo) / s - 1e-9)) + 1, 2)
        return np.linspace(lo, hi, n)
