"""Muscle mechanics: the parameters of a MuJoCo muscle actuator fitted to an OpenSim muscle.

MuJoCo's muscle (``<muscle>``, i.e. ``<general dyntype="muscle" gaintype="muscle"
biastype="muscle">``) has a rigid tendon: its force is a function of the actuator length
(here the MuJoCo tendon length, equal to OpenSim's muscle-tendon (MTU) length), the
lengthening velocity and the activation (``mju_muscleGain`` / ``mju_muscleBias``)::

    L0 = (lengthrange[1] - lengthrange[0]) / (range[1] - range[0])   # optimal length, m
    L  = range[0] + (length - lengthrange[0]) / L0                   # normalized length
    V  = velocity / (L0 * vmax)                                      # normalized velocity
    force = -F * (act * FL(L; lmin, lmax) * FV(V; fvmax) + FP(L; lmax, fpmax))

with FL a piecewise quadratic bump (0 outside ``[lmin, lmax]``, 1 at L = 1), FP zero below
L = 1, quadratic up to ``(1 + lmax) / 2`` where it reaches ``fpmax / 2``, linear beyond, and FV
quadratic from 0 (V = -1) through 1 (V = 0) up to ``fvmax``. :func:`o2m.mj.muscle.mujoco_muscle_force`
evaluates exactly this (the tests check it against ``mjData.actuator_force``).

:func:`fit_muscles` maps every muscle of an OpenSim model (Thelen2003Muscle,
Millard2012EquilibriumMuscle, Millard2012AccelerationMuscle, Schutte1993Muscle_Deprecated,
DeGrooteFregly2016Muscle, RigidTendonMuscle) to a :class:`MuscleParams`:

* ``lengthrange``: the smallest and largest MTU length OpenSim computes over random poses
  (every independent coordinate uniform in its range, seeded), the default pose, each
  coordinate at its range ends, and the range corners of the coordinates the muscle spans.
* ``force`` = max isometric force; ``timeconst`` from OpenSim's activation dynamics.
* ``range, lmin, lmax, fpmax`` by bounded least squares so that MuJoCo's static force matches
  OpenSim's static-equilibrium tendon force over the lengthrange at activation 1 (active +
  passive) and 0 (passive). OpenSim's forces come from a *bench*: a copy of the model's
  muscles, each with its own straight two-point path along a slider, so that its MTU length is
  set exactly; in static equilibrium (zero velocity) a muscle's tendon force depends on its
  MTU length and activation only, so the bench reproduces the full model's force at any pose
  with that MTU length (the tests check this against the full model).
* ``vmax``, ``fvmax`` fitted to OpenSim's force-velocity curve at optimal length over the speeds
  movements reach (:data:`FV_FIT_RANGE`), treating the tendon as rigid (MTU velocity = fiber
  velocity / cos(pennation)).

The errors are percentages of the max isometric force, over 197 lengths spanning the
lengthrange (the fit uses every fourth one).
"""

from __future__ import annotations

import concurrent.futures as cf
import functools
import math
import os
import tempfile
from copy import deepcopy
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from lxml import etree

from o2m.errors import ModelFileError
from o2m.mj.muscle import (
    MJMINVAL,
    active_force_length,
    force_velocity,
    mujoco_muscle_force,
    passive_force,
)
from o2m.osim import runtime
from o2m.osim.document import load_document
from o2m.osim.skeleton import Skipped
from o2m.parallel import worker_context

__all__ = [
    "MUJOCO_DEFAULTS",
    "SUPPORTED_MUSCLES",
    "FitResult",
    "MuscleParams",
    "error_summary",
    "fit_muscles",
]

#: OpenSim muscle types :func:`fit_muscles` maps.
SUPPORTED_MUSCLES = (
    "Thelen2003Muscle",
    "Millard2012EquilibriumMuscle",
    "Millard2012AccelerationMuscle",
    "Schutte1993Muscle_Deprecated",
    "DeGrooteFregly2016Muscle",
    "RigidTendonMuscle",
)

#: MuJoCo's defaults of the ``<muscle>`` shortcut.
MUJOCO_DEFAULTS = {
    "timeconst": (0.01, 0.04),
    "range": (0.75, 1.05),
    "lmin": 0.5,
    "lmax": 1.6,
    "vmax": 1.5,
    "fpmax": 1.3,
    "fvmax": 1.2,
}

#: Lengths (across the lengthrange) at which OpenSim's forces are computed and errors reported.
N_EVAL = 197
#: The fit uses every FIT_STRIDE-th of them (50 lengths).
FIT_STRIDE = 4
#: Random restarts of the length fit besides the two deterministic starts (more change the
#: bundled models' RMS errors by < 0.05 % of max isometric force).
N_RANDOM_STARTS = 2
#: The force-velocity curve is fitted over normalized fiber velocities -FV_FIT_RANGE..FV_FIT_RANGE
#: (fractions of the max contraction velocity), the speeds movements reach: in the MoBL-ARMS
#: dataset 99 % of the muscle states are within ±0.17. Fitted over ±1 instead, MuJoCo's quadratic
#: curve trades the slope at rest for the far ends, and the mean joint error against OpenSim
#: (19 MoBL-ARMS test sets) is 0.111 rad instead of 0.096, on Arm26 (five 0.3-s excitations)
#: 0.140 rad instead of 0.086.
FV_FIT_RANGE = 0.2
#: At most this many range corners are evaluated for one set of spanned coordinates.
MAX_CORNERS = 256

# Bounds of the fitted parameters: range[0], range width, lmin, lmax, fpmax.
_LOWER = np.array([0.0, 1e-3, 0.0, 1.0 + 1e-4, 1e-3])
_UPPER = np.array([4.0, 8.0, 1.0 - 1e-4, 6.0, 100.0])


# ---------------------------------------------------------------------------------------------
# Result type
# ---------------------------------------------------------------------------------------------


@dataclass
class MuscleParams:
    """Parameters of the MuJoCo muscle actuator for one OpenSim muscle, and how well it fits.

    ``force`` N; ``timeconst`` (activation, deactivation) s; ``range`` normalized operating
    lengths at ``lengthrange`` (m, MTU length); ``lmin, lmax, vmax, fpmax, fvmax`` as MuJoCo
    defines them. ``err_*_pct``: MuJoCo's static force minus OpenSim's static tendon force, in
    % of ``force``, max |.| and RMS over the lengthrange, at activation 1 (active) and 0
    (passive). ``cost`` and ``start_cost`` are the RMS (% of force, both activations together)
    of the fit and of its starting point (``start``), so ``cost <= start_cost``.
    ``lengths``, ``opensim_active``, ``opensim_passive`` hold OpenSim's tendon force (N,
    positive when pulling) at the evaluated MTU lengths (m); NaN where OpenSim found no
    equilibrium. ``velocity_rms_pct`` is the RMS error of the force-velocity fit (% of force at
    optimal length, over normalized fiber velocities within ±:data:`FV_FIT_RANGE`).
    """

    name: str
    type: str
    force: float
    timeconst: np.ndarray
    range: np.ndarray
    lmin: float
    lmax: float
    vmax: float
    fpmax: float
    fvmax: float
    lengthrange: np.ndarray
    err_active_max_pct: float
    err_active_rms_pct: float
    err_passive_max_pct: float
    err_passive_rms_pct: float
    notes: list[str] = field(default_factory=list)
    cost: float = math.nan
    start_cost: float = math.nan
    start: dict[str, float] = field(default_factory=dict, repr=False)
    velocity_rms_pct: float = math.nan
    lengths: np.ndarray | None = field(default=None, repr=False)
    opensim_active: np.ndarray | None = field(default=None, repr=False)
    opensim_passive: np.ndarray | None = field(default=None, repr=False)

    def mjcf_attributes(self) -> dict[str, str]:
        """Attributes of a MuJoCo ``<muscle>`` element (besides name and tendon)."""

        def fmt(v) -> str:
            return " ".join(f"{float(x):.10g}" for x in np.atleast_1d(v))

        return {
            "timeconst": fmt(self.timeconst), "range": fmt(self.range), "force": fmt(self.force),
            "lmin": fmt(self.lmin), "lmax": fmt(self.lmax), "vmax": fmt(self.vmax),
            "fpmax": fmt(self.fpmax), "fvmax": fmt(self.fvmax), "lengthrange": fmt(self.lengthrange),
        }

    def apply_to(self, actuator) -> None:
        """Make a ``mujoco.MjsActuator`` this muscle (``set_to_muscle`` plus ``lengthrange``)."""
        actuator.set_to_muscle(
            timeconst=[float(t) for t in self.timeconst], tausmooth=0.0,
            range=[float(r) for r in self.range], force=float(self.force), scale=200.0,
            lmin=float(self.lmin), lmax=float(self.lmax), vmax=float(self.vmax),
            fpmax=float(self.fpmax), fvmax=float(self.fvmax),
        )
        actuator.lengthrange = [float(v) for v in self.lengthrange]


class FitResult(dict):
    """``{muscle name: MuscleParams}`` in model order; ``skipped`` lists the muscles of
    unsupported types (as :class:`o2m.skeleton.Skipped`), ``timings`` the seconds per stage."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.skipped: list[Skipped] = []
        self.timings: dict[str, float] = {}


# ---------------------------------------------------------------------------------------------
# MuJoCo's muscle model (engine_util_misc.c: mju_muscleGainLength, mju_muscleGain, mju_muscleBias)
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# OpenSim helpers
# ---------------------------------------------------------------------------------------------


def _opensim():
    return runtime.opensim()


def _prop(obj, name: str, default: float | None = None) -> float:
    """A double property of an OpenSim object, by name (works for any concrete type)."""
    osim = _opensim()
    if not obj.hasProperty(name):
        if default is None:
            raise KeyError(name)
        return default
    return float(osim.PropertyHelper.getValueDouble(obj.getPropertyByName(name)))


def _bool_prop(obj, name: str) -> bool:
    osim = _opensim()
    if not obj.hasProperty(name):
        return False
    return bool(osim.PropertyHelper.getValueBool(obj.getPropertyByName(name)))


def _sample_bounds(coord) -> tuple[float, float]:
    lo, hi = float(coord.getRangeMin()), float(coord.getRangeMax())
    default = 1.0 if coord.getMotionType() == 2 else math.pi  # 2 = translational
    lo = lo if math.isfinite(lo) else -default
    hi = hi if math.isfinite(hi) else default
    return (lo, hi) if lo <= hi else (hi, lo)


class _PoseModel:
    """The full OpenSim model, for MTU lengths at poses given by the independent coordinates."""

    def __init__(self, osim_path: str):
        osim = _opensim()
        try:
            self.model = osim.Model(osim_path)
            self.state = self.model.initSystem()
        except Exception as exc:  # OpenSim raises generic RuntimeErrors
            raise ModelFileError(f"{osim_path}: OpenSim could not load the model: {exc}") from exc
        s = self.state
        cs = self.model.getCoordinateSet()
        coords = [cs.get(i) for i in range(cs.getSize())]
        self.indep = [c for c in coords if not c.getLocked(s) and not c.isDependent(s)]
        self.indep_names = [c.getName() for c in self.indep]
        self.bounds = np.array([_sample_bounds(c) for c in self.indep], dtype=float).reshape(-1, 2)
        self.defaults = np.array([c.getValue(s) for c in self.indep], dtype=float)
        ms = self.model.getMuscles()
        self.muscles = [ms.get(i) for i in range(ms.getSize())]
        self.muscle_names = [m.getName() for m in self.muscles]
        self.muscle_types = [m.getConcreteClassName() for m in self.muscles]
        self.couplers = self._coupler_chain(osim, coords)

    def _coupler_chain(self, osim, coords) -> list | None:
        """When every enforced constraint is a CoordinateCouplerConstraint, the couplers in an
        order that evaluates each dependent after the coordinates it depends on: (dependent,
        independents, function, scale factor). Setting dependents from them satisfies the
        constraints exactly, as assembly would (to its tolerance), at a fraction of the cost.
        None when other constraints need OpenSim's assembler."""
        s = self.state
        by_name = {c.getName(): c for c in coords}
        cs = self.model.getConstraintSet()
        pending = []
        for i in range(cs.getSize()):
            con = cs.get(i)
            if not con.isEnforced(s):
                continue
            if con.getConcreteClassName() != "CoordinateCouplerConstraint":
                return None
            cc = osim.CoordinateCouplerConstraint.safeDownCast(con)
            names = cc.getIndependentCoordinateNames()
            indep = [names.get(j) for j in range(names.getSize())]
            dep = cc.getDependentCoordinateName()
            if dep not in by_name or any(n not in by_name for n in indep):
                return None
            pending.append((dep, indep, cc.getFunction(), _prop(cc, "scale_factor", 1.0)))
        deps = {p[0] for p in pending}
        done: set[str] = set()
        chain = []
        while pending:
            ready = [p for p in pending if all(n not in deps or n in done for n in p[1])]
            if not ready:
                return None  # cyclic couplers: leave them to the assembler
            for p in ready:
                chain.append((by_name[p[0]], [by_name[n] for n in p[1]], p[2], p[3]))
                done.add(p[0])
                pending.remove(p)
        return chain

    def pose(self, q: np.ndarray):
        """A state with the independent coordinates at ``q`` and every constraint satisfied."""
        osim = _opensim()
        st = osim.State(self.state)
        for c, v in zip(self.indep, q, strict=True):
            c.setValue(st, float(v), False)
        if self.couplers is None:
            self.model.assemble(st)
        else:
            for dep, indep, fn, scale in self.couplers:
                x = osim.Vector(len(indep), 0.0)
                for j, c in enumerate(indep):
                    x.set(j, c.getValue(st))
                dep.setValue(st, scale * fn.calcValue(x), False)
        self.model.realizePosition(st)
        return st

    def lengths(self, poses: np.ndarray) -> np.ndarray:
        """(n_poses, n_muscles) MTU lengths; a pose OpenSim fails to assemble gives NaNs."""
        out = np.full((len(poses), len(self.muscles)), np.nan)
        for k, q in enumerate(poses):
            try:
                st = self.pose(q)
            except Exception:  # assembly failure: leave the pose out
                continue
            out[k] = [m.getLength(st) for m in self.muscles]
        return out


_WORKER_MODELS: dict[str, _PoseModel] = {}


def _worker_lengths(osim_path: str, poses: np.ndarray) -> np.ndarray:
    pm = _WORKER_MODELS.get(osim_path)
    if pm is None:
        pm = _WORKER_MODELS[osim_path] = _PoseModel(osim_path)
    return pm.lengths(poses)


# -- the bench ---------------------------------------------------------------------------------

_BENCH_PATH = """<GeometryPath name="path"><PathPointSet><objects>
<PathPoint name="origin"><socket_parent_frame>/ground</socket_parent_frame><location>0 0 0</location></PathPoint>
<PathPoint name="insertion"><socket_parent_frame>/bodyset/{body}</socket_parent_frame>
<location>0 0 0</location></PathPoint>
</objects></PathPointSet></GeometryPath>"""

_BENCH_BODY = """<Body name="{body}"><mass>1</mass><mass_center>0 0 0</mass_center>
<inertia>1 1 1 0 0 0</inertia></Body>"""

_BENCH_JOINT = """<SliderJoint name="slider_{i}"><socket_parent_frame>ground_offset</socket_parent_frame>
<socket_child_frame>{body}_offset</socket_child_frame>
<coordinates><Coordinate name="length_{i}"><default_value>{default}</default_value><range>0 1000</range>
<clamped>false</clamped></Coordinate></coordinates>
<frames><PhysicalOffsetFrame name="ground_offset"><socket_parent>/ground</socket_parent>
<translation>0 0 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
<PhysicalOffsetFrame name="{body}_offset"><socket_parent>/bodyset/{body}</socket_parent>
<translation>0 0 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame></frames></SliderJoint>"""


def _bench_document(elements: list[etree._Element]) -> str:
    """An OpenSim document in which muscle i (a copy of ``elements[i]`` with its path replaced)
    runs straight from the ground origin to body i, which slides along ground x: its MTU length
    is coordinate ``length_i``."""
    bodies, joints, forces = [], [], []
    for i, src in enumerate(elements):
        el = deepcopy(src)
        body = f"bench_body_{i}"
        for ch in list(el):
            if not isinstance(ch.tag, str):
                el.remove(ch)
            elif ch.tag.endswith("Path") or ch.tag in ("path", "GeometryPath"):
                idx = list(el).index(ch)
                el.remove(ch)
                el.insert(idx, etree.fromstring(_BENCH_PATH.format(body=body)))
            elif ch.tag in ("appliesForce", "isDisabled"):
                el.remove(ch)
        lopt = float(el.findtext("optimal_fiber_length") or 0.1)
        lts = float(el.findtext("tendon_slack_length") or 0.1)
        bodies.append(_BENCH_BODY.format(body=body))
        joints.append(_BENCH_JOINT.format(i=i, body=body, default=lopt + lts))
        forces.append(etree.tostring(el, encoding="unicode"))
    return (
        '<?xml version="1.0" encoding="UTF-8" ?>\n<OpenSimDocument Version="40600"><Model name="o2m_bench">'
        "<gravity>0 0 0</gravity>"
        f'<BodySet name="bodyset"><objects>{"".join(bodies)}</objects></BodySet>'
        f'<JointSet name="jointset"><objects>{"".join(joints)}</objects></JointSet>'
        f'<ForceSet name="forceset"><objects>{"".join(forces)}</objects></ForceSet>'
        "</Model></OpenSimDocument>"
    )


class _Bench:
    """OpenSim's static tendon force of each muscle as a function of its MTU length."""

    def __init__(self, elements: list[etree._Element]):
        osim = _opensim()
        with tempfile.TemporaryDirectory(prefix="o2m-bench-") as tmp:
            path = Path(tmp) / "bench.osim"
            path.write_text(_bench_document(elements))
            try:
                self.model = osim.Model(str(path))
                self.state = self.model.initSystem()
            except Exception as exc:  # a muscle's own properties are invalid
                raise ModelFileError(f"OpenSim rejects the model's muscles: {exc}") from exc
        cs = self.model.getCoordinateSet()
        self.coords = [cs.get(f"length_{i}") for i in range(len(elements))]
        ms = self.model.getMuscles()
        self.muscles = [ms.get(el.get("name")) for el in elements]

    def forces(self, lengths: np.ndarray, activation: float) -> tuple[np.ndarray, np.ndarray]:
        """Tendon forces (n_muscles, n) at MTU ``lengths`` (n_muscles, n), zero velocity, in
        static equilibrium; NaN where OpenSim finds none. Also returns the activation OpenSim
        actually used (its minimum-activation clamps apply)."""
        s = self.state
        nm, n = lengths.shape
        out = np.full((nm, n), np.nan)
        used = np.full((nm, n), np.nan)
        for j in range(n):
            for c, v in zip(self.coords, lengths[:, j], strict=True):
                c.setValue(s, float(v), False)
                c.setSpeedValue(s, 0.0)
            # the activation state, and the excitation (the muscle's control) for muscles whose
            # activation is their excitation (RigidTendonMuscle, ignore_activation_dynamics)
            for m in self.muscles:
                m.setActivation(s, activation)
            self.model.realizeVelocity(s)
            controls = self.model.updControls(s)
            for m in self.muscles:
                m.setControls(_opensim().Vector(1, float(activation)), controls)
            self.model.setControls(s, controls)
            ok = np.ones(nm, dtype=bool)
            for i, m in enumerate(self.muscles):
                try:
                    m.computeEquilibrium(s)
                except Exception:  # no equilibrium at this length
                    ok[i] = False
            try:
                self.model.realizeDynamics(s)
            except Exception:
                continue
            for i, m in enumerate(self.muscles):
                if ok[i]:
                    f = float(m.getTendonForce(s))
                    if math.isfinite(f):
                        out[i, j] = f
                        used[i, j] = float(m.getActivation(s))
        return out, used


# -- per-type properties -----------------------------------------------------------------------


def _downcast(muscle, type_name: str):
    osim = _opensim()
    cls = getattr(osim, type_name, None)
    return cls.safeDownCast(muscle) if cls is not None and hasattr(cls, "safeDownCast") else muscle


def _activation_times(m, type_name: str, notes: list[str]) -> tuple[float, float]:
    """MuJoCo (activation, deactivation) time constants for an OpenSim muscle."""
    if type_name in ("Thelen2003Muscle", "Millard2012EquilibriumMuscle", "DeGrooteFregly2016Muscle"):
        ta, td = _prop(m, "activation_time_constant"), _prop(m, "deactivation_time_constant")
        if _bool_prop(m, "ignore_activation_dynamics"):
            notes.append("OpenSim ignores activation dynamics (activation = excitation); MuJoCo's "
                         "muscle filters with the muscle's time constants")
        return ta, td
    if type_name == "Millard2012AccelerationMuscle":
        model = _downcast(m, type_name).get_MuscleFirstOrderActivationDynamicModel()
        return _prop(model, "activation_time_constant"), _prop(model, "deactivation_time_constant")
    if type_name == "Schutte1993Muscle_Deprecated":
        ts, a1, a2 = _prop(m, "time_scale"), _prop(m, "activation1"), _prop(m, "activation2")
        ta, td, rms, rms_step = _schutte_time_constants(ts, a1, a2)
        notes.append(f"Schutte activation dynamics (da/dt = (u - a)(a1 u + a2)/ts rising, (u - a) a2/ts falling) "
                     f"mapped to MuJoCo's time constants {ta:.4g}/{td:.4g} s, fitted to follow it under random "
                     f"excitations: activation RMS error {rms:.4f} (matching a full step's rise and decay "
                     f"instead: {rms_step:.4f})")
        return ta, td
    notes.append("RigidTendonMuscle has no activation dynamics; MuJoCo's default time constants 0.01/0.04 s")
    return MUJOCO_DEFAULTS["timeconst"]


#: Excitations the Schutte activation mapping is fitted on: slow sines as in the paper's sets, up to
#: this frequency (Hz), active with probability 1.
ACTIVATION_FIT_SETS, ACTIVATION_FIT_MAX_FREQ = 24, 3.0


@functools.lru_cache(maxsize=16)
def _schutte_time_constants(ts: float, a1: float, a2: float) -> tuple[float, float, float, float]:
    """MuJoCo (activation, deactivation) time constants (s) that best follow Schutte's dynamics.

    Schutte1993's activation rises at ``(u - a)(a1 u + a2)/ts`` and falls at ``(u - a) a2/ts``: its
    rise is fast only when the excitation is high. MuJoCo's muscle uses ``(u - a)/tau`` with
    ``tau = tact (0.5 + 1.5 a)`` rising and ``tdeact / (0.5 + 1.5 a)`` falling. Matching a full
    step's 0-90 % rise (the former mapping) makes MuJoCo rise about 3.6 times too fast at the
    moderate excitations of movements; here both are integrated (Schutte at 0.1 ms, MuJoCo as it
    steps, 2 ms with step-mean controls) under seeded random sine excitations and the time
    constants minimise the RMS difference of the activations. Returns the two time constants,
    that RMS and the RMS of the step-matched mapping.
    """
    from scipy.optimize import minimize

    from o2m.activations import generate_activations

    sets = generate_activations(["m"], ACTIVATION_FIT_SETS, seed=0, p_active=1.0, max_freq=ACTIVATION_FIT_MAX_FREQ)
    u = sets.values[:, :, 0]  # (sets, T) at 2 ms
    dt, sub = 0.002, 20
    # Schutte, Euler at dt/sub on the linearly interpolated excitation, sampled every dt
    fine = np.linspace(0.0, 1.0, sub, endpoint=False)
    a = np.zeros_like(u)
    act = np.zeros(u.shape[0])
    for k in range(u.shape[1] - 1):
        a[:, k] = act
        for f in fine:
            uk = u[:, k] + f * (u[:, k + 1] - u[:, k])
            rate = np.where(uk >= act, (uk - act) * (a1 * uk + a2), (uk - act) * a2) / ts
            act = act + (dt / sub) * rate
    a[:, -1] = act
    ctrl = 0.5 * (u[:, :-1] + u[:, 1:])

    def mujoco_rms(log_t: np.ndarray) -> float:
        t_act, t_deact = np.exp(log_t)
        b = np.zeros(u.shape[0])
        err = 0.0
        for k in range(ctrl.shape[1]):
            tau = np.where(ctrl[:, k] > b, t_act * (0.5 + 1.5 * b), t_deact / (0.5 + 1.5 * b))
            b = np.clip(b + dt * (ctrl[:, k] - b) / tau, 0.0, 1.0)  # MuJoCo's Euler update, activation clamped
            err += float(np.sum((b - a[:, k + 1]) ** 2))
        return math.sqrt(err / ctrl.size)

    tau_a, tau_d = ts / (a1 + a2), ts / a2
    step = np.log([tau_a * math.log(10) / (2 * math.log(10) - 1.35), tau_d * math.log(10) / (2 * math.log(6.5 / 2))])
    best = minimize(mujoco_rms, step, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-7})
    x = best.x if best.fun < mujoco_rms(step) else step
    return float(math.exp(x[0])), float(math.exp(x[1])), float(mujoco_rms(x)), float(mujoco_rms(step))


def _tabulated_inverse(v_of_f, f_lo: float, f_hi: float, u: np.ndarray) -> np.ndarray:
    """fv(u) for a monotone fiber-velocity(force) function: tabulate and interpolate."""
    f = np.linspace(f_lo, f_hi, 4001)
    v = np.array([v_of_f(x) for x in f])
    order = np.argsort(v)
    return np.interp(u, v[order], f[order])


def _force_velocity(m, type_name: str, u: np.ndarray) -> tuple[np.ndarray, float, list[str]]:
    """OpenSim's force-velocity multiplier at full activation and optimal length, at normalized
    fiber velocities ``u`` (fiber velocity / (vmax * optimal fiber length), negative =
    shortening), and vmax in optimal fiber lengths per second."""
    osim = _opensim()
    notes: list[str] = []
    if type_name == "Thelen2003Muscle":
        af, flen = _prop(m, "Af"), _prop(m, "Flen")
        thr = _prop(m, "fv_linear_extrap_threshold", 0.95)

        def dlce(fm: float) -> float:  # Thelen2003Muscle::calcdlceN at a = 1, fal = 1
            asy_e = flen
            if 0.0 < fm < asy_e * thr:
                b = 1.0 + fm / af if fm <= 1.0 else (2 + 2 / af) * (flen - fm) / (flen - 1)
                return (fm - 1.0) / b
            fm0 = 0.0 if fm <= 0.0 else thr * asy_e
            if fm0 == 0.0:
                b, db = 1.0 + fm0 / af, 1 / af
            else:
                b, db = (2 + 2 / af) * (flen - fm0) / (flen - 1), -(2 + 2 / af) / (flen - 1)
            d0 = (fm0 - 1.0) / b
            slope = 1.0 / b - (fm0 - 1.0) / (b * b) * db
            return d0 + slope * (fm - fm0)

        fv = _tabulated_inverse(dlce, -0.5, flen * 1.2, u)
        return np.maximum(fv, 0.0), _prop(m, "max_contraction_velocity"), notes
    if type_name in ("Millard2012EquilibriumMuscle", "Millard2012AccelerationMuscle"):
        curve = _downcast(m, type_name).getForceVelocityCurve()
        fv = np.array([curve.calcValue(float(x)) for x in u])
        return fv, _prop(m, "max_contraction_velocity"), notes
    if type_name == "DeGrooteFregly2016Muscle":
        fv = np.array([osim.DeGrooteFregly2016Muscle.calcForceVelocityMultiplier(float(x)) for x in u])
        return fv, _prop(m, "max_contraction_velocity"), notes
    if type_name == "RigidTendonMuscle":
        fn = _downcast(m, type_name).get_force_velocity_curve()
        fv = np.array([fn.calcValue(osim.Vector(1, float(x))) for x in u])
        return fv, _prop(m, "max_contraction_velocity"), notes
    # Schutte1993Muscle_Deprecated::calcFiberVelocity (velocity in optimal lengths per time_scale)
    d = _prop(m, "damping")
    kv, slope_k, fmax = 0.15, 0.13, 1.4

    def vel(f: float) -> float:
        if f < -d:
            return f / d
        if f < 1.0:
            c = kv * (f - 1.0) / d
            b = -kv * (f / kv + 1.0 + d) / d
            return (-b - math.sqrt(b * b - 4 * c)) / 2.0
        c = -(slope_k * kv / (d * (kv + 1))) * (f - 1.0)
        b = -(f / d - fmax / d - slope_k * kv / (kv + 1))
        return (-b + math.sqrt(b * b - 4 * c)) / 2.0

    ts = _prop(m, "time_scale")
    fv = _tabulated_inverse(vel, -d, fmax + 1.0, u)
    notes.append(f"Schutte force-velocity: max shortening velocity taken as 1/time_scale = {1 / ts:.3g} "
                 "optimal fiber lengths/s")
    return np.maximum(fv, 0.0), 1.0 / ts, notes


# ---------------------------------------------------------------------------------------------
# Fitting (pure numpy/scipy; runs in worker processes)
# ---------------------------------------------------------------------------------------------


@dataclass
class _FitTask:
    name: str
    type: str
    force: float
    lopt: float
    lts: float
    alpha: float
    vmax_os: float
    lengthrange: np.ndarray
    lengths: np.ndarray
    active: np.ndarray
    passive: np.ndarray
    fv_u: np.ndarray
    fv: np.ndarray
    timeconst: tuple[float, float]
    notes: list[str]
    seed: int


def _residuals(x, s, ya, yp, ma, mp) -> np.ndarray:
    """Residuals (MuJoCo minus OpenSim, in max isometric forces) at activation 1 then 0, for
    x = (range[0], range width, lmin, lmax, fpmax) at lengths s (0..1 across the lengthrange)."""
    r0, w, lmin, lmax, fpmax = x
    L = r0 + s * w
    fp = passive_force(L, lmax, fpmax)
    return np.concatenate([(active_force_length(L, lmin, lmax) + fp - ya)[ma], (fp - yp)[mp]])


def _jacobian(x, s, ya, yp, ma, mp) -> np.ndarray:
    """d residuals / d x of :func:`_residuals` (the derivatives of MuJoCo's piecewise curves)."""
    r0, w, lmin, lmax, fpmax = x
    L = r0 + s * w
    a, b = 0.5 * (lmin + 1.0), 0.5 * (1.0 + lmax)
    dn, up = max(MJMINVAL, 1.0 - lmin), max(MJMINVAL, lmax - 1.0)
    inside = (L >= lmin) & (L <= lmax)
    lo_half, hi_half = L <= 1.0, L > 1.0
    # active curve: pieces [lmin, a], (a, 1], (1, b], (b, lmax]; x_k as in mju_muscleGainLength
    xl = np.where(L <= a, 2 * (L - lmin) / dn, 2 * (1.0 - L) / dn)
    xh = np.where(L <= b, 2 * (L - 1.0) / up, 2 * (lmax - L) / up)
    dfl_dL = np.where(inside, np.where(lo_half, xl * 2 / dn, -xh * 2 / up), 0.0)
    dfl_dlmin = np.where(inside & lo_half, xl * 2 * (L - 1.0) / dn**2, 0.0)
    dfl_dlmax = np.where(inside & hi_half, xh * 2 * (L - 1.0) / up**2, 0.0)
    # passive curve
    h = 0.5 * up
    xq = (L - 1.0) / h
    quad = L <= b
    dfp_dL = np.where(hi_half, np.where(quad, fpmax * xq / h, fpmax / h), 0.0)
    dfp_dlmax = np.where(hi_half, -fpmax * (L - 1.0) / (2 * h * h) * np.where(quad, xq, 1.0), 0.0)
    dfp_dfpmax = np.where(hi_half, np.where(quad, 0.5 * xq * xq, 0.5 + (L - b) / h), 0.0)
    zero = np.zeros_like(L)
    ja = np.column_stack([dfl_dL + dfp_dL, (dfl_dL + dfp_dL) * s, dfl_dlmin, dfl_dlmax + dfp_dlmax, dfp_dfpmax])
    jp = np.column_stack([dfp_dL, dfp_dL * s, zero, dfp_dlmax, dfp_dfpmax])
    return np.concatenate([ja[ma], jp[mp]])


def _start_point(t: _FitTask) -> np.ndarray:
    """MuJoCo's defaults with ``range`` from OpenSim's tendon slack and optimal fiber length:
    the normalized fiber length of a rigid tendon, linearized at optimal length,
    L = 1 + (l - lts - lopt cos a) cos a / lopt."""
    ca = math.cos(t.alpha)
    r = 1.0 + (t.lengthrange - t.lts - t.lopt * ca) * ca / t.lopt
    x = np.array([r[0], r[1] - r[0], MUJOCO_DEFAULTS["lmin"], MUJOCO_DEFAULTS["lmax"], MUJOCO_DEFAULTS["fpmax"]])
    return np.clip(x, _LOWER, _UPPER)


def _fit_length(t: _FitTask) -> tuple[np.ndarray, np.ndarray, float, float]:
    from scipy.optimize import least_squares

    idx = np.arange(0, len(t.lengths), FIT_STRIDE)
    lengths = t.lengths[idx]
    ya, yp = t.active[idx] / t.force, t.passive[idx] / t.force
    ma, mp = np.isfinite(ya), np.isfinite(yp)
    s = (lengths - t.lengthrange[0]) / max(MJMINVAL, t.lengthrange[1] - t.lengthrange[0])
    args = (s, ya, yp, ma, mp)

    def cost(x):
        r = _residuals(x, *args)
        return float(r @ r)

    x_start = _start_point(t)
    default = np.clip(np.array([MUJOCO_DEFAULTS["range"][0], MUJOCO_DEFAULTS["range"][1] - MUJOCO_DEFAULTS["range"][0],
                                MUJOCO_DEFAULTS["lmin"], MUJOCO_DEFAULTS["lmax"], MUJOCO_DEFAULTS["fpmax"]]),
                      _LOWER, _UPPER)
    rng = np.random.default_rng(t.seed)  # the same restarts for every muscle: same data, same fit
    starts = [x_start, default]
    for _ in range(N_RANDOM_STARTS):
        x = x_start.copy()
        x[0] = x_start[0] + rng.normal(0.0, 0.15)
        x[1] = x_start[1] * math.exp(rng.normal(0.0, 0.3))
        x[2] = rng.uniform(0.2, 0.8)
        x[3] = rng.uniform(1.2, 2.4)
        x[4] = math.exp(rng.uniform(math.log(0.1), math.log(10.0)))
        starts.append(np.clip(x, _LOWER, _UPPER))
    best, best_cost = x_start, cost(x_start)
    start_cost = best_cost
    if ma.any() or mp.any():
        for x0 in starts:
            try:
                res = least_squares(_residuals, x0, jac=_jacobian, bounds=(_LOWER, _UPPER), args=args,
                                    method="trf", x_scale=np.array([0.1, 0.1, 0.1, 0.1, 0.3]), max_nfev=200,
                                    ftol=1e-6, xtol=1e-6, gtol=1e-6)
            except ValueError:
                continue
            c = cost(res.x)
            if c < best_cost:
                best, best_cost = res.x, c
    n = max(1, int(ma.sum() + mp.sum()))
    return best, x_start, 100 * math.sqrt(best_cost / n), 100 * math.sqrt(start_cost / n)


@functools.lru_cache(maxsize=64)
def _fv_shape(u_bytes: bytes, fv_bytes: bytes) -> tuple[float, float, float]:
    """(c, fvmax, RMS) of the MuJoCo force-velocity curve FV(c u; fvmax) closest to OpenSim's
    fv(u) in least squares, u = normalized fiber velocity."""
    from scipy.optimize import least_squares

    u, fv = np.frombuffer(u_bytes), np.frombuffer(fv_bytes)
    ok = np.isfinite(fv)
    u, fv = u[ok], fv[ok]

    def res(p):
        return force_velocity(p[0] * u, p[1]) - fv

    lo, hi = np.array([0.2, 1.0]), np.array([5.0, 3.0])
    best, best_cost = None, math.inf
    for start in (np.array([1.0, MUJOCO_DEFAULTS["fvmax"]]), np.array([1.5, 1.6])):
        r = least_squares(res, start, bounds=(lo, hi), method="trf")
        cst = float(r.fun @ r.fun)
        if cst < best_cost:
            best, best_cost = r.x, cst
    return float(best[0]), float(best[1]), 100 * math.sqrt(best_cost / max(1, len(u)))


def _fit_velocity(t: _FitTask, L0: float) -> tuple[float, float, float]:
    """vmax, fvmax and the RMS error (% of force) of MuJoCo's force-velocity curve against
    OpenSim's, over normalized fiber velocities ±FV_FIT_RANGE, taking the tendon as rigid: the MTU
    lengthens at fiber velocity / cos(pennation at optimal length)."""
    c, fvmax, rms = _fv_shape(np.ascontiguousarray(t.fv_u, dtype=float).tobytes(),
                              np.ascontiguousarray(t.fv, dtype=float).tobytes())
    mtu_vmax = t.vmax_os * t.lopt / max(math.cos(t.alpha), 1e-6)  # m/s at OpenSim's max fiber speed
    return float(mtu_vmax / max(MJMINVAL, L0 * c)), fvmax, rms


def _errors(p: MuscleParams, t: _FitTask) -> None:
    fa = -mujoco_muscle_force(p, t.lengths, 0.0, 1.0)
    fp = -mujoco_muscle_force(p, t.lengths, 0.0, 0.0)
    ea = (fa - t.active) / t.force * 100
    ep = (fp - t.passive) / t.force * 100
    ea, ep = ea[np.isfinite(ea)], ep[np.isfinite(ep)]
    p.err_active_max_pct = float(np.max(np.abs(ea))) if ea.size else math.nan
    p.err_active_rms_pct = float(np.sqrt(np.mean(ea**2))) if ea.size else math.nan
    p.err_passive_max_pct = float(np.max(np.abs(ep))) if ep.size else math.nan
    p.err_passive_rms_pct = float(np.sqrt(np.mean(ep**2))) if ep.size else math.nan


def _fit_one(t: _FitTask) -> MuscleParams:
    x, x0, cost, start_cost = _fit_length(t)
    r0, w, lmin, lmax, fpmax = (float(v) for v in x)
    rng = np.array([r0, r0 + w])
    L0 = (t.lengthrange[1] - t.lengthrange[0]) / w
    vmax, fvmax, vel_rms = _fit_velocity(t, L0)
    p = MuscleParams(
        name=t.name, type=t.type, force=t.force, timeconst=np.array(t.timeconst, dtype=float), range=rng,
        lmin=lmin, lmax=lmax, vmax=vmax, fpmax=fpmax, fvmax=fvmax, lengthrange=t.lengthrange.copy(),
        err_active_max_pct=math.nan, err_active_rms_pct=math.nan, err_passive_max_pct=math.nan,
        err_passive_rms_pct=math.nan, notes=list(t.notes), cost=cost, start_cost=start_cost,
        start={"range0": float(x0[0]), "range1": float(x0[0] + x0[1]), "lmin": float(x0[2]),
               "lmax": float(x0[3]), "fpmax": float(x0[4])},
        velocity_rms_pct=vel_rms, lengths=t.lengths, opensim_active=t.active, opensim_passive=t.passive,
    )
    _errors(p, t)
    return p


# ---------------------------------------------------------------------------------------------
# The driver
# ---------------------------------------------------------------------------------------------


def _muscle_elements(doc, names: list[str]) -> dict[str, etree._Element]:
    """The ForceSet XML element of each named muscle (4.x document)."""
    out: dict[str, etree._Element] = {}
    fs = doc.model.find("ForceSet")
    objects = fs.find("objects") if fs is not None else None
    if objects is not None:
        for el in objects:
            if isinstance(el.tag, str) and el.get("name") in names:
                out.setdefault(el.get("name"), el)
    return out


def _corner_poses(bounds: np.ndarray, defaults: np.ndarray, coords: tuple[int, ...],
                  rng: np.random.Generator) -> np.ndarray:
    k = len(coords)
    if k == 0:
        return np.empty((0, len(defaults)))
    if 2**k <= MAX_CORNERS:
        bits = (np.arange(2**k)[:, None] >> np.arange(k)[None, :]) & 1
    else:
        bits = rng.integers(0, 2, size=(MAX_CORNERS, k))
    poses = np.repeat(defaults[None, :], len(bits), axis=0)
    cols = np.array(coords)
    poses[:, cols] = np.where(bits == 1, bounds[cols, 1], bounds[cols, 0])
    return poses


def _lengths_parallel(pool, osim_path: str, poses: np.ndarray, n_chunks: int) -> np.ndarray:
    chunks = [c for c in np.array_split(poses, n_chunks) if len(c)]
    futures = [pool.submit(_worker_lengths, osim_path, c) for c in chunks]
    return np.concatenate([f.result() for f in futures], axis=0)


def fit_muscles(osim_path: str | os.PathLike, *, n_poses: int = 300, seed: int = 0, progress: bool = False,
                processes: int | None = None) -> FitResult:
    """Fit a MuJoCo muscle actuator to every muscle of the OpenSim model at ``osim_path``.

    Returns a :class:`FitResult`, a dict ``{muscle name: MuscleParams}`` in model order, whose
    ``skipped`` lists muscles of types o2m does not map (with the reason). ``n_poses`` random
    poses (seeded by ``seed``) plus the default pose, each coordinate's range ends and the range
    corners of each muscle's coordinates give the lengthranges. ``processes`` worker processes
    (default: all cores; 1 = none) share the pose sampling and the fits; the result does not
    depend on it. Raises :class:`o2m.errors.ModelFileError` when OpenSim cannot load the model.
    """
    import time

    from tqdm.auto import tqdm

    osim_path = os.fspath(osim_path)
    if not os.path.isfile(osim_path):
        raise ModelFileError(f"{osim_path}: no such file")
    processes = max(1, int(processes if processes is not None else (os.cpu_count() or 1)))
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    bar = tqdm(total=4, disable=not progress, desc=f"muscles {os.path.basename(osim_path)}")

    pm = _PoseModel(osim_path)
    result = FitResult()
    supported = [i for i, t in enumerate(pm.muscle_types) if t in SUPPORTED_MUSCLES]
    for i, t in enumerate(pm.muscle_types):
        if t not in SUPPORTED_MUSCLES:
            result.skipped.append(Skipped(t, pm.muscle_names[i], (
                f"muscle type {t} is not mapped to a MuJoCo muscle (o2m maps {', '.join(SUPPORTED_MUSCLES)})")))
    if not supported:
        result.timings = {"total": time.perf_counter() - t0}
        bar.close()
        return result

    pool: cf.ProcessPoolExecutor | None = None

    def get_pool() -> cf.ProcessPoolExecutor:
        nonlocal pool
        if pool is None:
            import scipy.optimize  # noqa: F401  (imported once here, inherited by forked workers)

            pool = cf.ProcessPoolExecutor(max_workers=processes, mp_context=worker_context())
        return pool

    try:
        # -- 1. lengthranges ----------------------------------------------------------------
        nq = len(pm.indep)
        rng = np.random.default_rng(seed)
        random_poses = rng.uniform(pm.bounds[:, 0], pm.bounds[:, 1], size=(n_poses, nq))
        ends = [pm.defaults.copy()]
        for i in range(nq):
            for v in pm.bounds[i]:
                q = pm.defaults.copy()
                q[i] = v
                ends.append(q)
        ends = np.array(ends).reshape(-1, nq)
        len_ends = pm.lengths(ends)
        # coordinates each muscle spans: its length changes when the coordinate goes to a range end
        nm = len(pm.muscles)
        delta = np.abs(len_ends[1:] - len_ends[0][None, :]).reshape(nq, 2, nm).max(axis=1) if nq else np.zeros((0, nm))
        spans = {i: tuple(int(k) for k in np.flatnonzero(delta[:, i] > 1e-7)) for i in supported}
        corner_rng = np.random.default_rng([seed, 1])
        corner_poses = [_corner_poses(pm.bounds, pm.defaults, s, corner_rng) for s in sorted(set(spans.values()))]
        rest = np.concatenate([random_poses, *corner_poses], axis=0)
        if processes > 1 and pm.couplers is None and len(rest) >= 200:
            # OpenSim's assembler is the slow part (~5 ms a pose): share it out
            len_rest = _lengths_parallel(get_pool(), osim_path, rest, 2 * processes)
        else:
            len_rest = pm.lengths(rest)
        all_lengths = np.concatenate([len_ends, len_rest], axis=0)
        n_failed = int(np.isnan(all_lengths[:, 0]).sum()) if all_lengths.size else 0
        timings["lengthrange"] = time.perf_counter() - t0
        bar.update()

        # -- 2. OpenSim's static forces on the bench ---------------------------------------
        t1 = time.perf_counter()
        doc = load_document(osim_path)
        names = [pm.muscle_names[i] for i in supported]
        elements = _muscle_elements(doc, names)
        missing = [n for n in names if n not in elements]
        if missing:
            raise ModelFileError(f"{osim_path}: muscle(s) {', '.join(missing)} not found in the ForceSet")
        bench = _Bench([elements[n] for n in names])
        notes = {n: [] for n in names}
        lr = np.zeros((len(names), 2))
        for k, i in enumerate(supported):
            col = all_lengths[:, i]
            col = col[np.isfinite(col)]
            lo, hi = float(col.min()), float(col.max())
            if hi - lo < 1e-6:
                pad = max(1e-4, 0.005 * hi)
                notes[names[k]].append(f"MTU length is constant ({hi:.6g} m) over the coordinate ranges; "
                                       f"lengthrange padded by {pad:.3g} m")
                lo, hi = lo - pad, hi + pad
            lr[k] = lo, hi
            if n_failed:
                notes[names[k]].append(f"{n_failed} sampled pose(s) failed to assemble and were left out")
        grid = lr[:, :1] + (lr[:, 1:] - lr[:, :1]) * np.linspace(0.0, 1.0, N_EVAL)[None, :]
        f_act, a_act = bench.forces(grid, 1.0)
        f_pas, a_pas = bench.forces(grid, 0.0)
        u = np.linspace(-FV_FIT_RANGE, FV_FIT_RANGE, 201)
        tasks = []
        for k, (name, i) in enumerate(zip(names, supported, strict=True)):
            m = bench.muscles[k]
            type_name = pm.muscle_types[i]
            nt = notes[name]
            if elements[name].findtext("appliesForce", "true").strip().lower() in ("false", "0") or \
                    elements[name].findtext("isDisabled", "false").strip().lower() in ("true", "1"):
                nt.append("the muscle is disabled in the OpenSim model (fitted as if enabled)")
            for what, f, a_used, target in (("activation 1", f_act[k], a_act[k], 1.0),
                                            ("activation 0", f_pas[k], a_pas[k], 0.0)):
                bad = int(np.isnan(f).sum())
                if bad:
                    nt.append(f"OpenSim found no static equilibrium at {bad} of {N_EVAL} lengths at {what}")
                a_ok = a_used[np.isfinite(a_used)]
                if a_ok.size and abs(float(np.median(a_ok)) - target) > 1e-9:
                    nt.append(f"OpenSim clamps {what} to {float(np.median(a_ok)):.3g}")
            timeconst = _activation_times(m, type_name, nt)
            fv, vmax_os, fv_notes = _force_velocity(m, type_name, u)
            nt.extend(fv_notes)
            tasks.append(_FitTask(
                name=name, type=type_name, force=_prop(m, "max_isometric_force"),
                lopt=_prop(m, "optimal_fiber_length"), lts=_prop(m, "tendon_slack_length"),
                alpha=_prop(m, "pennation_angle_at_optimal", 0.0), vmax_os=vmax_os, lengthrange=lr[k].copy(),
                lengths=grid[k].copy(), active=f_act[k].copy(), passive=f_pas[k].copy(), fv_u=u, fv=fv,
                timeconst=(float(timeconst[0]), float(timeconst[1])), notes=nt, seed=seed,
            ))
        timings["opensim_forces"] = time.perf_counter() - t1
        bar.update()

        # -- 3. fits -------------------------------------------------------------------------
        t2 = time.perf_counter()
        if processes > 1 and len(tasks) >= 8:
            fitted = list(get_pool().map(_fit_one, tasks, chunksize=max(1, len(tasks) // (4 * processes))))
        else:
            fitted = [_fit_one(t) for t in tasks]
        timings["fit"] = time.perf_counter() - t2
        bar.update()
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)

    for p in fitted:
        result[p.name] = p
    timings["total"] = time.perf_counter() - t0
    result.timings = timings
    bar.update()
    bar.close()
    return result


def error_summary(results: FitResult | dict[str, MuscleParams]) -> dict[str, float]:
    """Worst and RMS (over muscles and lengths) errors of a model's fits, % of max isometric force:
    keys ``active_max``, ``active_rms``, ``passive_max``, ``passive_rms`` and ``n``."""
    ps = list(results.values())
    if not ps:
        return {"n": 0, "active_max": math.nan, "active_rms": math.nan, "passive_max": math.nan,
                "passive_rms": math.nan}

    def agg(attr_max: str, attr_rms: str) -> tuple[float, float]:
        mx = max(getattr(p, attr_max) for p in ps)
        rms = math.sqrt(sum(getattr(p, attr_rms) ** 2 for p in ps) / len(ps))
        return float(mx), float(rms)

    am, ar = agg("err_active_max_pct", "err_active_rms_pct")
    pmx, pr = agg("err_passive_max_pct", "err_passive_rms_pct")
    return {"n": len(ps), "active_max": am, "active_rms": ar, "passive_max": pmx, "passive_rms": pr}
