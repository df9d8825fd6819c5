"""OpenSim's side of the muscle fit: MTU lengths over sampled poses, and static tendon forces on
a bench over the lengthranges they give.

Lengths are metres, forces newtons; only path lengths are read from poses, so OpenSim's Y-up
ground does not enter. :func:`measure_muscles` gathers all a fit needs of one muscle in a
:class:`MuscleSample` (with :mod:`o2m.convert.muscle_types`' time constants and force-velocity
curve); :mod:`o2m.convert.muscles` fits MuJoCo's muscle to it.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from copy import deepcopy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from lxml import etree

from o2m.convert.muscle_types import _activation_times, _force_velocity, _prop, fiber_damping
from o2m.errors import ModelFileError
from o2m.osim import runtime
from o2m.osim.couplers import coupler_chain, satisfy_constraints
from o2m.osim.document import OsimDocument, load_document, opensim_reason, opensim_refusal
from o2m.osim.names import opensim_coordinate_names
from o2m.osim.simulate import tendon_force
from o2m.osim.spikes import unfair_path

__all__ = ["FV_FIT_RANGE", "N_EVAL", "LengthSamples", "MuscleSample", "length_island", "measure_muscles",
           "sample_lengths"]

#: Lengths (across the lengthrange) at which OpenSim's forces are computed and errors reported.
N_EVAL = 197
#: The force-velocity curve is fitted over normalized fiber velocities -FV_FIT_RANGE..FV_FIT_RANGE
#: (fractions of the max contraction velocity), the speeds movements reach: in the MoBL-ARMS
#: dataset 99 % of the muscle states are within ±0.17. Fitted over ±1 instead, MuJoCo's quadratic
#: curve trades the slope at rest for the far ends, and the mean joint error against OpenSim
#: (19 MoBL-ARMS test sets) is 0.111 rad instead of 0.096, on Arm26 (five 0.3-s excitations)
#: 0.140 rad instead of 0.086.
FV_FIT_RANGE = 0.2
#: At most this many range corners are evaluated for one set of spanned coordinates.
MAX_CORNERS = 256
#: A muscle's longest (or shortest) sampled lengths are an island, left out of its lengthrange
#: (:func:`length_island`), when they are at most this fraction of its samples ...
ISLAND_FRACTION = 0.02
#: ... beyond a gap in the sorted lengths wider than this fraction of the other lengths' spread ...
ISLAND_GAP = 0.5
#: ... and OpenSim's length steps by over this fraction of the gap within one of ISLAND_LINE_STEPS
#: steps along the straight line (in coordinates) from each island pose to its nearest other
#: sampled pose: a continuous length over the coordinates' box takes every value between its
#: samples, so only a step leaves such a gap.
ISLAND_STEP = 0.5
ISLAND_LINE_STEPS = 64
#: The tests of OpenSim's path (``test`` of :func:`~o2m.osim.spikes.unfair_path`) by their codes
#: in :attr:`LengthSamples.failures` (0: none), and how the report names them.
FAILURE_TESTS = {"detour": 1, "loop": 2, "winding": 3, "inconsistent": 4}
FAILURE_NAMES = {1: "detour", 2: "loop", 3: "winding", 4: "length not of its drawn path"}


@dataclass
class LengthSamples:
    """OpenSim's MTU lengths over sampled poses: ``poses`` (n, independent coordinates, rad or m),
    ``lengths`` (n, muscles, m; NaN where a pose did not assemble), ``failures`` (n, muscles) the code
    (:data:`FAILURE_TESTS`) of the test OpenSim's path fails there, 0 for none, and ``n_failed``
    the poses OpenSim could not assemble (whole rows of NaN)."""

    poses: np.ndarray
    lengths: np.ndarray
    failures: np.ndarray
    n_failed: int


@dataclass
class MuscleSample:
    """What OpenSim says about one muscle, all a fit needs: its properties (``force`` N,
    ``lopt``, ``lts`` m, pennation ``alpha`` rad, ``vmax_os`` optimal fiber lengths/s), its
    ``lengthrange`` (m), static tendon forces (N) at activation 1 (``active``) and 0
    (``passive``) at the MTU ``lengths`` (m), the force-velocity multiplier ``fv`` at normalized
    fiber velocities ``fv_u``, MuJoCo time constants ``timeconst`` (s), the notes so far, the
    ``seed`` of the fit's random restarts, ``min_activation``, the activation OpenSim uses when
    asked for 0 (Thelen's and Millard's ``minimum_activation``; ``passive`` is taken there), and
    ``default_activation``, its activation in OpenSim's default state (NaN for a muscle without
    an activation state), and ``fiber_damping``, normalized (:func:`~o2m.convert.muscle_types.fiber_damping`)."""

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
    min_activation: float = 0.0
    default_activation: float = math.nan
    fiber_damping: float = 0.0


# ---------------------------------------------------------------------------------------------
# Poses and lengths
# ---------------------------------------------------------------------------------------------


class _PoseModel:
    """The full OpenSim model, for MTU lengths at poses given by the independent coordinates."""

    def __init__(self, osim_path: str):
        osim = runtime.opensim()
        try:
            self.model = osim.Model(osim_path)
            self.state = self.model.initSystem()
        except Exception as exc:  # OpenSim raises generic RuntimeErrors
            raise opensim_refusal(osim_path, exc) from None
        s = self.state
        cs = self.model.getCoordinateSet()
        coords = [cs.get(i) for i in range(cs.getSize())]
        self.indep = [c for c in coords if not runtime.is_held(c, s) and not c.isDependent(s)]
        mj_names = opensim_coordinate_names(self.model)
        self.indep_names = [mj_names[c.getAbsolutePathString()] for c in self.indep]
        self.bounds = np.array([runtime.sample_bounds(c) for c in self.indep], dtype=float).reshape(-1, 2)
        self.defaults = np.array([c.getValue(s) for c in self.indep], dtype=float)
        ms = self.model.getMuscles()
        self.muscles = [ms.get(i) for i in range(ms.getSize())]
        self.muscle_names = [m.getName() for m in self.muscles]
        self.muscle_types = [m.getConcreteClassName() for m in self.muscles]
        self.wrapped = [i for i, n in enumerate(self.muscle_names)
                        if runtime.geometry_path(self.model, n).getWrapSet().getSize()]
        self.couplers = coupler_chain(self.model, s)

    def pose(self, q: np.ndarray):
        """A state with the independent coordinates at ``q`` and every constraint satisfied."""
        osim = runtime.opensim()
        st = osim.State(self.state)
        for c, v in zip(self.indep, q, strict=True):
            c.setValue(st, float(v), False)
        satisfy_constraints(self.model, self.couplers, st)
        self.model.realizePosition(st)
        return st

    def lengths(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n_poses, n_muscles) MTU lengths (m) and failure codes (:data:`FAILURE_TESTS`). A pose
        OpenSim fails to assemble gives NaNs; a code marks a muscle whose path fails as a path there
        (:func:`~o2m.osim.spikes.unfair_path`, the comparison's own tests)."""
        out = np.full((len(poses), len(self.muscles)), np.nan)
        codes = np.zeros(out.shape, dtype=np.int8)
        for k, q in enumerate(poses):
            try:
                st = self.pose(q)
            except Exception:  # assembly failure: leave the pose out
                continue
            out[k] = [m.getLength(st) for m in self.muscles]
            for i in self.wrapped:
                found = unfair_path(self.model, st, self.muscle_names[i], out[k, i])
                if found is not None:
                    codes[k, i] = FAILURE_TESTS[found["test"]]
        return out, codes

    def length_along(self, muscle: int, start: np.ndarray, end: np.ndarray, steps: int) -> np.ndarray:
        """OpenSim's MTU length (m) of muscle index ``muscle`` at ``steps`` + 1 poses evenly along
        the straight line from pose ``start`` to ``end``; NaN where a pose fails to assemble."""
        out = np.full(steps + 1, np.nan)
        for k, t in enumerate(np.linspace(0.0, 1.0, steps + 1)):
            try:
                out[k] = self.muscles[muscle].getLength(self.pose(start + t * (end - start)))
            except Exception:  # assembly failure
                continue
        return out


_WORKER_MODELS: dict[str, _PoseModel] = {}


def _worker_lengths(osim_path: str, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pm = _WORKER_MODELS.get(osim_path)
    if pm is None:
        pm = _WORKER_MODELS[osim_path] = _PoseModel(osim_path)
    return pm.lengths(poses)


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


def _lengths_parallel(pool, osim_path: str, poses: np.ndarray, n_chunks: int) -> tuple[np.ndarray, np.ndarray]:
    chunks = [c for c in np.array_split(poses, n_chunks) if len(c)]
    results = [f.result() for f in [pool.submit(_worker_lengths, osim_path, c) for c in chunks]]
    return np.concatenate([r[0] for r in results], axis=0), np.concatenate([r[1] for r in results], axis=0)


def sample_lengths(pm: _PoseModel, osim_path: str, supported: list[int], n_poses: int, seed: int, processes: int,
                   get_pool: Callable[[], Any]) -> LengthSamples:
    """MTU lengths of the model ``pm`` (read from ``osim_path``) at ``n_poses`` random poses
    (seeded by ``seed``), the default pose, each coordinate at its range ends and the range corners
    of the coordinates each ``supported`` muscle spans. With ``processes`` > 1 the poses are shared
    out on the pool ``get_pool()``."""
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
    len_ends, fail_ends = pm.lengths(ends)
    # coordinates each muscle spans: its length changes when the coordinate goes to a range end
    nm = len(pm.muscles)
    with np.errstate(invalid="ignore"):  # inf - inf where a length is not finite (measure_muscles names the muscle)
        delta = np.abs(len_ends[1:] - len_ends[0][None, :]).reshape(nq, 2, nm).max(axis=1) if nq else np.zeros((0, nm))
    spans = {i: tuple(int(k) for k in np.flatnonzero(delta[:, i] > 1e-7)) for i in supported}
    corner_rng = np.random.default_rng([seed, 1])
    corner_poses = [_corner_poses(pm.bounds, pm.defaults, s, corner_rng) for s in sorted(set(spans.values()))]
    rest = np.concatenate([random_poses, *corner_poses], axis=0)
    if processes > 1 and pm.couplers is None and len(rest) >= 200:
        # OpenSim's assembler is the slow part (~5 ms a pose): share it out
        len_rest, fail_rest = _lengths_parallel(get_pool(), osim_path, rest, 2 * processes)
    else:
        len_rest, fail_rest = pm.lengths(rest)
    lengths = np.concatenate([len_ends, len_rest], axis=0)
    failures = np.concatenate([fail_ends, fail_rest], axis=0)
    n_failed = int(np.isnan(lengths).all(axis=1).sum()) if lengths.size else 0
    return LengthSamples(np.concatenate([ends, rest], axis=0), lengths, failures, n_failed)


def length_island(poses: np.ndarray, lengths: np.ndarray,
                  length_along: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> dict[str, Any] | None:
    """The samples at one end of a muscle's sorted ``lengths`` (n,) m, at ``poses`` (n, nq), that
    OpenSim reaches only through a step of its length: at most :data:`ISLAND_FRACTION` of them,
    beyond a gap over :data:`ISLAND_GAP` of the other lengths' spread, each with a step of over
    :data:`ISLAND_STEP` of the gap between two of the lengths ``length_along(start, end)`` gives
    along the line from its pose to the nearest other pose (coordinates scaled by their spread).
    A muscle works at the lengths its poses fill; OpenSim's wrap flickering on the long way round
    in a thin slice of poses (MoBL-ARMS's TMIN at high shoulder elevation, twice its length
    elsewhere) would otherwise spread its lengthrange, and with it the force fit, over lengths it
    never works at.
    Returns {"index" (island sample indices), "gap", "rest" (m, the other lengths' min and max),
    "step" (m, the smallest island's largest one-step change)}, or None."""
    finite = np.flatnonzero(np.isfinite(lengths))
    order = finite[np.argsort(lengths[finite])]
    n = len(order)
    k_max = int(ISLAND_FRACTION * n)
    if k_max < 1:
        return None
    values = lengths[order]
    scale = np.maximum(np.ptp(poses[finite], axis=0), 1e-12)
    for top in (True, False):
        ranked = values[::-1] if top else values
        gaps = np.abs(np.diff(ranked[:k_max + 1]))
        k = int(np.argmax(gaps)) + 1  # the island: the first k of ranked
        rest = ranked[k:]
        gap = float(gaps[k - 1])
        if gap <= ISLAND_GAP * float(np.ptp(rest)):
            continue
        island = order[::-1][:k] if top else order[:k]
        others = order[::-1][k:] if top else order[k:]
        steps = []
        for j in island:
            near = others[np.argmin(np.linalg.norm((poses[others] - poses[j]) / scale, axis=1))]
            along = length_along(poses[j], poses[near])
            steps.append(float(np.nanmax(np.abs(np.diff(along)))) if np.isfinite(along).sum() > 1 else 0.0)
        if min(steps) > ISLAND_STEP * gap:
            return {"index": island, "gap": gap, "rest": (float(rest.min()), float(rest.max())),
                    "step": min(steps)}
    return None


def _lengthranges(samples: LengthSamples, supported: list[int], names: list[str],
                  pm: _PoseModel | None = None) -> tuple[np.ndarray, dict[str, list[str]]]:
    """(lengthrange (muscles, 2) m, notes per muscle) of the ``supported`` muscles (named ``names``)
    from the sampled lengths, leaving out OpenSim's path failures and, with ``pm`` to walk its
    lines, a :func:`length_island`; a constant length is padded."""
    notes = {n: [] for n in names}
    lr = np.zeros((len(names), 2))
    for k, i in enumerate(supported):
        col = samples.lengths[:, i].copy()
        codes = samples.failures[:, i]
        kinds = ", ".join(f"{int((codes == c).sum())} {FAILURE_NAMES[c]}" for c in sorted(set(codes[codes > 0])))
        if np.isfinite(col[codes == 0]).any():
            # no tendon reaches the length of a path that fails as a path: it must not stretch the lengthrange
            col[codes > 0] = np.nan
            if kinds:
                notes[names[k]].append(f"{int((codes > 0).sum())} sampled pose(s) left out of the lengthrange "
                                       f"where OpenSim's path fails as a path ({kinds}; o2m.osim.spikes)")
        elif kinds:
            notes[names[k]].append(f"OpenSim's path fails as a path at every sampled pose ({kinds}; "
                                   "o2m.osim.spikes): the lengthrange is of those lengths")
        island = None if pm is None else length_island(
            samples.poses, col, lambda a, b, i=i: pm.length_along(i, a, b, ISLAND_LINE_STEPS))
        if island is not None:
            idx = island["index"]
            notes[names[k]].append(
                f"{len(idx)} sampled pose(s) left out of the lengthrange: OpenSim's length there "
                f"({np.min(col[idx]):.4g}-{np.max(col[idx]):.4g} m) lies {island['gap']:.3g} m beyond its other "
                f"lengths ({island['rest'][0]:.4g}-{island['rest'][1]:.4g} m), reached only through a step of "
                f"{island['step']:.3g} m (o2m.convert.muscle_samples.length_island)")
            col[idx] = np.nan
        col = col[np.isfinite(col)]
        lo, hi = float(col.min()), float(col.max())
        if hi - lo < 1e-6:
            pad = max(1e-4, 0.005 * hi)
            notes[names[k]].append(f"MTU length is constant ({hi:.6g} m) over the coordinate ranges; "
                                   f"lengthrange padded by {pad:.3g} m")
            lo, hi = lo - pad, hi + pad
        lr[k] = lo, hi
        if samples.n_failed:
            notes[names[k]].append(f"{samples.n_failed} sampled pose(s) failed to assemble and were left out")
    return lr, notes


# ---------------------------------------------------------------------------------------------
# The bench
# ---------------------------------------------------------------------------------------------


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


def _bench_refusal(doc: OsimDocument, elements: list[etree._Element], exc: Exception) -> Exception:
    """The error for OpenSim's refusal of the bench: naming the muscle (of ``elements``, read from
    ``doc``) that OpenSim names, its line and OpenSim's reason."""
    component, reason = opensim_reason(exc)
    name = component.split("/")[2] if component and component.startswith("/forceset/") else None
    el = next((e for e in elements if name is not None and e.get("name") == name), None)
    if el is None:
        return ModelFileError(f"{doc.path}: OpenSim rejects the model's muscles: {reason}")
    return doc.error(el, f"makes OpenSim refuse the muscle: {reason}")


class _Bench:
    """OpenSim's static tendon force of each muscle as a function of its MTU length."""

    def __init__(self, doc: OsimDocument, elements: list[etree._Element]):
        osim = runtime.opensim()
        with tempfile.TemporaryDirectory(prefix="o2m-bench-") as tmp:
            path = Path(tmp) / "bench.osim"
            path.write_text(_bench_document(elements))
            try:
                self.model = osim.Model(str(path))
                self.state = self.model.initSystem()
            except Exception as exc:  # a muscle's own properties are invalid
                raise _bench_refusal(doc, elements, exc) from None
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
                m.setControls(runtime.opensim().Vector(1, float(activation)), controls)
            self.model.setControls(s, controls)
            ok = np.ones(nm, dtype=bool)
            for i, m in enumerate(self.muscles):
                try:
                    m.computeEquilibrium(s)
                except Exception:  # no equilibrium at this length
                    ok[i] = False
            try:
                self.model.realizeDynamics(s)
            except RuntimeError:  # a muscle without dynamics (see _equilibrium_force): read each as it is
                pass
            for i, m in enumerate(self.muscles):
                f = _equilibrium_force(m, s) if ok[i] else math.nan
                if math.isfinite(f):
                    out[i, j] = f
                    used[i, j] = float(m.getActivation(s))
        return out, used


def _equilibrium_force(m, s) -> float:
    """The tendon force (N) of muscle ``m`` just brought to equilibrium in state ``s``
    (:func:`~o2m.osim.simulate.tendon_force`: OpenSim 4.6's deprecated fiber-length muscles leave
    it in their actuation); NaN where OpenSim has none for this state."""
    try:
        return tendon_force(m, s)
    except RuntimeError:
        return math.nan


def _muscle_elements(doc, names: list[str]) -> dict[str, etree._Element]:
    """The ForceSet XML element of each named muscle (4.x document)."""
    out: dict[str, etree._Element] = {}
    # the ForceSet's objects, then the model's <components> (where a 4.x model may keep forces)
    for el in doc.model.iterfind("ForceSet/objects/*"):
        if isinstance(el.tag, str) and el.get("name") in names:
            out.setdefault(el.get("name"), el)
    for el in doc.model.iterfind("components/*"):
        if isinstance(el.tag, str) and el.get("name") in names:
            out.setdefault(el.get("name"), el)
    return out


def measure_muscles(osim_path: str, pm: _PoseModel, supported: list[int], samples: LengthSamples,
                    seed: int) -> list[MuscleSample]:
    """OpenSim's measurements of the ``supported`` muscles of ``pm`` (indices into its muscles), in
    order: lengthranges from ``samples`` (:func:`sample_lengths`), static forces over them on the
    bench, time constants and force-velocity curves."""
    doc = load_document(osim_path)
    names = [pm.muscle_names[i] for i in supported]
    elements = _muscle_elements(doc, names)
    missing = [n for n in names if n not in elements]
    if missing:
        raise ModelFileError(f"{osim_path}: muscle(s) {', '.join(missing)} not found in the ForceSet")
    for k, i in enumerate(supported):
        if not np.isfinite(samples.lengths[:, i]).any():
            raise doc.error(elements[names[k]], f"has no finite length at any of the {len(samples.lengths)} poses "
                                                "sampled (OpenSim gives inf or NaN: a path point too far out?)")
    bench = _Bench(doc, [elements[n] for n in names])
    lr, notes = _lengthranges(samples, supported, names, pm)
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
        tasks.append(MuscleSample(
            name=name, type=type_name, force=_prop(m, "max_isometric_force"),
            lopt=_prop(m, "optimal_fiber_length"), lts=_prop(m, "tendon_slack_length"),
            alpha=_prop(m, "pennation_angle_at_optimal", 0.0), vmax_os=vmax_os, lengthrange=lr[k].copy(),
            lengths=grid[k].copy(), active=f_act[k].copy(), passive=f_pas[k].copy(), fv_u=u, fv=fv,
            timeconst=(float(timeconst[0]), float(timeconst[1])), notes=nt, seed=seed,
            min_activation=_floor_activation(a_pas[k]),
            default_activation=_default_activation(pm.muscles[i], pm.state),
            fiber_damping=fiber_damping(m, type_name),
        ))
    return tasks


def _default_activation(muscle, state) -> float:
    """The activation state of OpenSim ``muscle`` in the model's default ``state`` (its
    ``default_activation``, whatever the muscle class keeps it as), NaN where it has none."""
    try:  # the state variable: getActivation would realise the muscle's dynamics first
        a = float(muscle.getStateVariableValue(state, "activation"))
    except RuntimeError:
        return math.nan
    return a if math.isfinite(a) else math.nan


def _floor_activation(used: np.ndarray) -> float:
    """The activation OpenSim used when asked for 0 (median over the lengths where it found an
    equilibrium), 0 when it used 0 or found none."""
    finite = used[np.isfinite(used)]
    return float(np.clip(np.median(finite), 0.0, 1.0)) if finite.size else 0.0
