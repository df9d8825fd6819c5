"""Fitting each MuJoCo muscle to OpenSim's tendon forces along OpenSim's own trajectories.

MuJoCo's muscle has a rigid tendon and fixed curve shapes; OpenSim's muscles (MoBL-ARMS'
Schutte1993 muscles, Thelen's, Millard's) have an elastic tendon and, some, damped fibres. The
static fit of :mod:`o2m.muscles` matches the two at rest, but at the states a movement visits the
forces still differ: on MoBL-ARMS by 1.7 % of max isometric force RMS over 8 training
trajectories, 5 % for DELT1, whose errors alone put about 4 N m on shoulder elevation. This
module fits each muscle to OpenSim's tendon force at the states of OpenSim's trajectories (the
dataset records them, :mod:`o2m.dataset`), with this force (N, positive when pulling)::

    F = scale F0 act FL(Ln; lmin, lmax) FV(Vn; fvmax)  +  k1 d + k2 d² + k3 d³  +  c V
        Ln = range[0] + (L - lengthrange[0]) / L0,  L0 = (lengthrange[1] - lengthrange[0]) / (range[1] - range[0])
        Vn = V / (L0 vmax),  d = max(L - edge, 0)

* the active part is MuJoCo's muscle gain (``range, lmin, lmax, vmax, fvmax`` and ``scale`` times
  the max isometric force F0);
* the passive part leaves MuJoCo's muscle bias (``fpmax`` set to :data:`TINY`) for the muscle's
  tendon: a one-sided polynomial spring with dead band ``[0, edge]`` (MuJoCo 4's polynomial
  tendon springs; OpenSim's exponential passive curve, which MuJoCo's quadratic-then-linear
  passive curve cannot follow) and tendon damping ``c`` (N s/m; an elastic tendon in series with
  damped fibres makes the passive force depend on speed).

``L`` and ``V`` are MuJoCo's actuator length (m) and velocity (m/s) at OpenSim's state, so the fit
also absorbs what the path approximations leave; ``act`` is the activation the caller gives:
:mod:`o2m.paper` gives MuJoCo's own activation for OpenSim's excitations
(:func:`o2m.mj.simulate.muscle_activations`), so the fit also absorbs what MuJoCo's activation
dynamics cannot copy of OpenSim's (and, in part, an elastic tendon's lag). When the samples carry
their controls (:func:`sample_states` with ``excitations``), each muscle's activation time
constants (MuJoCo's ``dynprm``: ``tau_act``, ``tau_deact``, ``tausmooth``) are fitted with the
curves, the activations integrated anew as MuJoCo steps them
(:func:`o2m.mj.muscle.integrate_activations`): OpenSim's tendon force lags MuJoCo's (Schutte's
activation rises with the excitation, not the activation, and an elastic tendon delays the force),
most for the long-tendoned forearm muscles. With ``ForceSamples.weight`` (:func:`sample_states`
with ``weight_coordinates``: the muscle's moment arms) each residual is weighted, so the fit
minimises the joint torque error rather than the force error. The fit is
bounded least squares (``scipy.optimize.least_squares``) in units of F0 over the training states
plus, weighted by ``static_weight``, OpenSim's static force curves at activation 1 and 0 (from
:func:`o2m.muscles.fit_muscles`), which keep the curves sane at lengths the trajectories do not
reach. Each muscle starts from the converted model's curves and keeps the start unless the fit
is better on held-out states (:attr:`MuscleForceFit.kept`).
"""

from __future__ import annotations

import copy
import json
import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from o2m.convert.muscles import fit_muscles
from o2m.mj.muscle import active_force_length, force_velocity, integrate_activations, passive_force
from o2m.paper.force_samples import ForceSamples, sample_states
from o2m.parallel import map_with_progress

__all__ = ["ForceFit", "MuscleForceFit", "ForceSamples", "TINY", "fit_forces", "pulling_force", "sample_states",
           "static_curves"]

TINY = 1e-9
"""``fpmax`` of a fitted muscle: MuJoCo needs it positive; the passive force is the tendon's spring."""
STATIC_WEIGHT = 1.0
"""Weight of the static curves against the trajectory states (each set weighs as much as the states)."""
#: Parameter order and bounds (log_vmax: natural log of vmax; k1..k3 in N/m, N/m², N/m³; damping N s/m).
PARAMETERS = ("range0", "width", "lmin", "lmax", "log_vmax", "fvmax", "scale", "edge", "k1", "k2", "k3",
              "damping")
_LOWER = np.array([0.0, 1e-3, 0.0, 1.0 + 1e-4, math.log(0.05), 1.0 + 1e-4, 0.5, -np.inf, 0.0, 0.0, 0.0, 0.0])
_UPPER = np.array([4.0, 8.0, 1.0 - 1e-4, 6.0, math.log(50.0), 3.0, 2.0, np.inf, np.inf, np.inf, np.inf, np.inf])
#: How far (m) beyond the actuator's lengthrange the spring's edge may go.
EDGE_MARGIN = 0.05
#: Bounds of the activation time constants (tau_act, tau_deact, tausmooth), s.
DYN_LOWER, DYN_UPPER = np.array([0.002, 0.01, 0.0]), np.array([0.2, 0.5, 2.0])


def pulling_force(model: mujoco.MjModel, muscle: str, length, velocity, activation) -> np.ndarray:
    """The force (N, positive when pulling) a MuJoCo muscle and its tendon's spring and damping
    exert at actuator ``length`` (m), ``velocity`` (m/s) and ``activation``, as MuJoCo computes it
    (``mju_muscleGain``, ``mju_muscleBias`` and the tendon's polynomial spring with its dead band);
    arrays broadcast. The muscle's tendon transmission must have gear 1, as o2m writes it."""
    a = model.actuator(muscle).id
    t = int(model.actuator_trnid[a, 0])
    g, b, lr = model.actuator_gainprm[a], model.actuator_biasprm[a], model.actuator_lengthrange[a]
    L, V = np.asarray(length, float), np.asarray(velocity, float)
    L0 = (lr[1] - lr[0]) / (g[1] - g[0])
    Ln = g[0] + (L - lr[0]) / L0
    active = (g[2] * np.asarray(activation, float) * active_force_length(Ln, g[4], g[5])
              * force_velocity(V / (L0 * g[6]), g[8]))
    passive = b[2] * passive_force(g[0] + (L - lr[0]) / ((lr[1] - lr[0]) / (b[1] - b[0])), b[5], b[7])
    lo, hi = model.tendon_lengthspring[t]
    d = np.where(L > hi, L - hi, np.where(L < lo, L - lo, 0.0))
    k1, (k2, k3) = model.tendon_stiffness[t], model.tendon_stiffnesspoly[t]
    return active + passive + d * (k1 + d * (k2 + d * k3)) + model.tendon_damping[t] * V


def static_curves(osim_path: str | os.PathLike[str], model: mujoco.MjModel) -> dict[str, tuple[np.ndarray, ...]]:
    """OpenSim's static tendon forces per muscle, at MuJoCo actuator lengths.

    ``{muscle: (lengths (m), force at activation 1 (N), force at activation 0 (N))}``, from the
    bench of :func:`o2m.muscles.fit_muscles`. OpenSim's MTU lengths are moved by the difference of
    the two lengthranges' lower ends (zero unless the converter's tendon leaves out a constant
    segment of OpenSim's path).
    """
    out = {}
    for name, p in fit_muscles(osim_path).items():
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        if aid < 0 or p.lengths is None:
            continue
        shift = float(model.actuator_lengthrange[aid, 0] - p.lengthrange[0])
        ok = np.isfinite(p.opensim_active) & np.isfinite(p.opensim_passive)
        out[name] = (p.lengths[ok] + shift, p.opensim_active[ok], p.opensim_passive[ok])
    return out


@dataclass
class MuscleForceFit:
    """One muscle's fitted force parameters (see the module docstring) and its errors.

    ``rms_start``, ``rms`` are RMS errors (% of F0) on the training states of the converted and the
    fitted force; ``rms_held_out_start``, ``rms_held_out`` the same on held-out states. ``kept``
    is False when the fit did not beat the start on held-out states (the start is used then).
    """

    name: str
    force: float
    lengthrange: list[float]
    range: list[float]
    lmin: float
    lmax: float
    vmax: float
    fvmax: float
    scale: float
    edge: float
    stiffness: list[float]
    damping: float
    rms_start: float
    rms: float
    rms_held_out_start: float
    rms_held_out: float
    kept: bool = True
    dynprm: list[float] | None = None  # (tau_act, tau_deact, tausmooth) s; None: the model's own

    def force_at(self, length, velocity, activation) -> np.ndarray:
        """The fitted force (N, positive when pulling) at MuJoCo actuator lengths (m), velocities (m/s), activations."""
        return _force(self._vector(), self.force, np.asarray(self.lengthrange), length, velocity, activation)

    def _vector(self) -> np.ndarray:
        w = self.range[1] - self.range[0]
        return np.array([self.range[0], w, self.lmin, self.lmax, math.log(self.vmax), self.fvmax, self.scale,
                         self.edge, *self.stiffness, self.damping])


def _force(x: np.ndarray, f0: float, lr: np.ndarray, length, velocity, activation) -> np.ndarray:
    r0, w, lmin, lmax, lvmax, fvmax, scale, edge, k1, k2, k3, c = x
    L0 = (lr[1] - lr[0]) / w
    Ln = r0 + (np.asarray(length) - lr[0]) / L0
    Vn = np.asarray(velocity) / (L0 * math.exp(lvmax))
    d = np.maximum(np.asarray(length) - edge, 0.0)
    spring = d * (k1 + d * (k2 + d * k3))
    fl, fv = active_force_length(Ln, lmin, lmax), force_velocity(Vn, fvmax)
    return scale * f0 * np.asarray(activation) * fl * fv + spring + c * np.asarray(velocity)


def _start(model: mujoco.MjModel, aid: int, static: tuple[np.ndarray, ...] | None) -> np.ndarray:
    """The converted muscle as a parameter vector: its gain curves, and a spring for its passive force.

    The spring's edge is where MuJoCo's passive curve starts (normalized length 1); its
    coefficients are the non-negative least-squares fit of OpenSim's static passive force (of the
    converted passive curve without ``static``).
    """
    from scipy.optimize import nnls

    g = model.actuator_gainprm[aid]
    lr = model.actuator_lengthrange[aid]
    r0, r1, lmin, lmax, vmax, fpmax, fvmax = g[0], g[1], g[4], g[5], g[6], g[7], g[8]
    f0 = float(g[2])
    L0 = (lr[1] - lr[0]) / (r1 - r0)
    edge = lr[0] + (1.0 - r0) * L0
    if static is None:  # the converted passive curve
        lengths = np.linspace(lr[0], lr[1], 200)
        passive = f0 * passive_force(r0 + (lengths - lr[0]) / L0, lmax, fpmax)
    else:  # OpenSim's own
        lengths, passive = static[0], static[2]
    d = np.maximum(lengths - edge, 0.0)
    k, _ = nnls(np.stack([d, d**2, d**3], axis=1), passive) if np.any(d > 0) else (np.zeros(3), 0.0)
    # damping starts at 1 % of the force-velocity slope at rest, F0 / (L0 vmax): small, but not at its bound
    x = np.array([r0, r1 - r0, lmin, lmax, math.log(vmax), fvmax, 1.0, edge, *k, 0.01 * f0 / (L0 * vmax)])
    lo, hi = _bounds(lr)
    return np.clip(x, lo, hi)


def _bounds(lr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = _LOWER.copy(), _UPPER.copy()
    # the edge is the upper end of the dead band [0, edge], which MuJoCo's compiler refuses below 0
    lo[7], hi[7] = max(0.0, lr[0] - EDGE_MARGIN), lr[1] + EDGE_MARGIN
    return lo, hi


@dataclass
class _Dynamics:
    """One muscle's activation inputs: controls (B, T - 1), initial activations (B,), and where
    each sample sits: trajectory and step, (N,) each."""

    controls: np.ndarray
    initial: np.ndarray
    trajectory: np.ndarray
    step: np.ndarray
    timestep: float

    def activations(self, dynprm: np.ndarray) -> np.ndarray:
        """The activation at every sample, (N,), for (tau_act, tau_deact, tausmooth) ``dynprm`` (s)."""
        act = integrate_activations(self.controls[..., None], self.initial[:, None], dynprm, self.timestep)
        return act[self.trajectory, self.step, 0]


@dataclass
class _Task:
    name: str
    f0: float
    lr: np.ndarray
    x0: np.ndarray
    train: tuple[np.ndarray, ...]  # length, velocity, activation, force
    held: tuple[np.ndarray, ...]
    static: tuple[np.ndarray, ...] | None
    static_weight: float
    max_nfev: int
    dyn0: np.ndarray | None = None  # the model's (tau_act, tau_deact, tausmooth), s
    train_dynamics: _Dynamics | None = None  # given, the time constants are fitted too
    held_dynamics: _Dynamics | None = None
    weight: np.ndarray | float = 1.0  # of each training residual


def _rms(x: np.ndarray, t: _Task, data: tuple[np.ndarray, ...]) -> float:
    if len(data[0]) == 0:
        return math.nan
    r = (_force(x, t.f0, t.lr, *data[:3]) - data[3]) / t.f0
    return float(100 * math.sqrt(np.mean(r * r)))


def _static_residuals(t: _Task, x: np.ndarray, n: int) -> list[np.ndarray]:
    """OpenSim's static curves at activation 1 and 0, weighted as ``n`` trajectory states."""
    if t.static is None:
        return []
    w = t.static_weight * math.sqrt(n / max(1, len(t.static[0])))
    ls, fa, fp = t.static
    zero = np.zeros_like(ls)
    return [w * (_force(x, t.f0, t.lr, ls, zero, 1.0) - fa) / t.f0,
            w * (_force(x, t.f0, t.lr, ls, zero, 0.0) - fp) / t.f0]


def _fit_curves(t: _Task, x0: np.ndarray, train: tuple[np.ndarray, ...]) -> np.ndarray:
    """Least squares of the force parameters on ``train`` (length, velocity, activation, force) and the
    static curves."""
    from scipy.optimize import least_squares

    L, V, A, F = train
    if not len(L):
        return x0

    def residuals(x: np.ndarray) -> np.ndarray:
        return np.concatenate([t.weight * (_force(x, t.f0, t.lr, L, V, A) - F) / t.f0,
                               *_static_residuals(t, x, len(L))])

    lo, hi = _bounds(t.lr)
    return least_squares(residuals, x0, bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=t.max_nfev).x


def _fit_with_dynamics(t: _Task, x0: np.ndarray, dyn: _Dynamics) -> tuple[np.ndarray, np.ndarray]:
    """Least squares of the force parameters and the activation time constants (s) together.

    The activations are integrated once per set of time constants (cached), so the force
    parameters' finite differences cost no integration.
    """
    from scipy.optimize import least_squares

    L, V, _, F = t.train
    n = len(x0)
    cache: dict[bytes, np.ndarray] = {}

    def activations(d: np.ndarray) -> np.ndarray:
        key = d.tobytes()
        if key not in cache:
            if len(cache) > 8:
                cache.clear()
            cache[key] = dyn.activations(d)
        return cache[key]

    def residuals(p: np.ndarray) -> np.ndarray:
        x, d = p[:n], p[n:]
        return np.concatenate([t.weight * (_force(x, t.f0, t.lr, L, V, activations(d)) - F) / t.f0,
                               *_static_residuals(t, x, len(L))])

    lo, hi = _bounds(t.lr)
    # the smoothing starts inside its bounds: at 0 MuJoCo switches hard and its slope is lost
    d0 = np.clip([t.dyn0[0], t.dyn0[1], max(t.dyn0[2], 0.05)], DYN_LOWER + 1e-9, DYN_UPPER - 1e-9)
    res = least_squares(residuals, np.concatenate([x0, d0]), bounds=(np.r_[lo, DYN_LOWER], np.r_[hi, DYN_UPPER]),
                        method="trf", x_scale="jac", max_nfev=t.max_nfev)
    return res.x[:n], res.x[n:]


def _with_activation(data: tuple[np.ndarray, ...], activation: np.ndarray) -> tuple[np.ndarray, ...]:
    return data[0], data[1], activation, data[3]


def _fit_one(t: _Task) -> MuscleForceFit:
    lo, hi = _bounds(t.lr)
    x0 = np.clip(t.x0, lo + 1e-12, hi - 1e-12)
    d0 = t.dyn0
    train0, held0 = t.train, t.held
    if t.train_dynamics is not None:  # the activations of the model's own time constants
        train0 = _with_activation(t.train, t.train_dynamics.activations(d0))
        if t.held_dynamics is not None and len(t.held[0]):
            held0 = _with_activation(t.held, t.held_dynamics.activations(d0))
    x, d, train, held = _fit_curves(t, x0, train0), d0, train0, held0
    if t.train_dynamics is not None and len(train0[0]):
        # the time constants absorb the lag of OpenSim's force (its activation dynamics and elastic
        # tendon) behind MuJoCo's, fitted with the curves, from the curves fitted at the model's own
        x, d = _fit_with_dynamics(t, x, t.train_dynamics)
        train = _with_activation(t.train, t.train_dynamics.activations(d))
        if t.held_dynamics is not None and len(t.held[0]):
            held = _with_activation(t.held, t.held_dynamics.activations(d))
    held_start, held_fit = _rms(x0, t, held0), _rms(x, t, held)
    kept = bool(not np.isfinite(held_fit) or held_fit <= held_start) and _rms(x, t, train) <= _rms(x0, t, train0)
    best, best_train, best_held = (x, train, held) if kept else (x0, train0, held0)
    r0, w, lmin, lmax, lvmax, fvmax, scale, edge, k1, k2, k3, c = (float(v) for v in best)
    dynprm = [float(v) for v in d] if kept and t.train_dynamics is not None else None
    return MuscleForceFit(t.name, t.f0, [float(v) for v in t.lr], [r0, r0 + w], lmin, lmax, math.exp(lvmax), fvmax,
                          scale, edge, [k1, k2, k3], c,
                          _rms(x0, t, train0), _rms(best, t, best_train), held_start, _rms(best, t, best_held), kept,
                          dynprm)


@dataclass
class ForceFit:
    """Fitted forces of every muscle; :meth:`apply` writes them into a model."""

    muscles: dict[str, MuscleForceFit]
    settings: dict = field(default_factory=dict)

    def apply(self, model: mujoco.MjModel) -> mujoco.MjModel:
        """A copy of ``model`` with every fitted muscle's gain, (tiny) bias and tendon spring and damping."""
        m = copy.copy(model)
        for name, f in self.muscles.items():
            a = model.actuator(name).id
            t = int(model.actuator_trnid[a, 0])
            prm = np.array([f.range[0], f.range[1], f.force * f.scale, model.actuator_gainprm[a, 3], f.lmin,
                            f.lmax, f.vmax, TINY, f.fvmax])
            m.actuator_gainprm[a, :9] = prm
            m.actuator_biasprm[a, :9] = prm
            m.tendon_stiffness[t] = f.stiffness[0]
            m.tendon_stiffnesspoly[t] = f.stiffness[1:]
            m.tendon_lengthspring[t] = [0.0, f.edge]
            m.tendon_damping[t] = f.damping
            if f.dynprm is not None:
                m.actuator_dynprm[a, :3] = f.dynprm
        return m

    def write_mjcf(self, xml_in: str | os.PathLike[str], xml_out: str | os.PathLike[str]) -> Path:
        """Write ``xml_in`` with the fitted muscles (full precision) to ``xml_out``."""
        from lxml import etree

        tree = etree.parse(str(xml_in))
        root = tree.getroot()

        def num(v) -> str:
            return " ".join(f"{float(x):.17g}" for x in np.atleast_1d(v))

        for name, f in self.muscles.items():
            act = root.find(f".//actuator/*[@name='{name}']")
            ten = root.find(f".//tendon/*[@name='{act.get('tendon')}']") if act is not None else None
            if act is None or ten is None:
                raise KeyError(f"{xml_in}: no muscle actuator and tendon named {name!r}")
            if act.tag == "muscle":
                for key, v in (("range", f.range), ("force", f.force * f.scale), ("lmin", f.lmin), ("lmax", f.lmax),
                               ("vmax", f.vmax), ("fpmax", TINY), ("fvmax", f.fvmax)):
                    act.set(key, num(v))
                if f.dynprm is not None:
                    act.set("timeconst", num(f.dynprm[:2]))
                    act.set("tausmooth", num(f.dynprm[2]))
            else:  # <general dyntype="muscle" ...> as MuJoCo writes it: keep the scale (gainprm[3])
                scale = float((act.get("gainprm") or "0 0 0 200").split()[3])
                prm = [f.range[0], f.range[1], f.force * f.scale, scale, f.lmin, f.lmax, f.vmax, TINY, f.fvmax]
                act.set("gainprm", num(prm))
                act.set("biasprm", num(prm))
                if f.dynprm is not None:
                    act.set("dynprm", num(f.dynprm))
            ten.set("stiffness", num(f.stiffness))
            ten.set("springlength", num([0.0, f.edge]))
            ten.set("damping", num(f.damping))
        out = Path(xml_out)
        tree.write(str(out), pretty_print=True)
        mujoco.MjModel.from_xml_path(str(out))  # it must load
        return out

    def summary(self) -> dict[str, float]:
        """Mean over muscles of the RMS errors (% of F0): start and fitted, training and held-out."""
        fs = list(self.muscles.values())

        def mean(attr: str) -> float:
            v = np.array([getattr(f, attr) for f in fs], float)
            return float(np.nanmean(v)) if v.size and np.isfinite(v).any() else math.nan

        return {k: mean(k) for k in ("rms_start", "rms", "rms_held_out_start", "rms_held_out")} | {
            "kept": int(sum(f.kept for f in fs)), "muscles": len(fs)}

    def save(self, path: str | os.PathLike[str]) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"settings": self.settings, "summary": self.summary(),
                                    "muscles": {k: asdict(v) for k, v in self.muscles.items()}}, indent=1) + "\n")
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> ForceFit:
        d = json.loads(Path(path).read_text())
        return cls({k: MuscleForceFit(**v) for k, v in d["muscles"].items()}, d.get("settings", {}))


def fit_forces(model: mujoco.MjModel, train: ForceSamples, *, held_out: ForceSamples | None = None,
               static: Mapping[str, tuple[np.ndarray, ...]] | None = None, static_weight: float = STATIC_WEIGHT,
               max_nfev: int = 600, processes: int | None = None, progress: bool = True,
               fit_dynamics: bool = True) -> ForceFit:
    """Fit every muscle in ``train.muscles`` (see the module docstring).

    ``held_out`` states decide whether each fit is kept (default: every fifth training
    trajectory is held out). ``static`` comes from :func:`static_curves`. ``max_nfev`` bounds the
    least-squares evaluations per muscle (of each stage). ``fit_dynamics``: when the samples carry
    their controls (:func:`sample_states` with ``excitations``), also fit each muscle's activation
    time constants (``dynprm``). The fits run in ``processes`` worker processes (default: all
    cores); the result does not depend on it.
    """
    if held_out is None:
        traj = np.unique(train.trajectory)
        held_rows = np.isin(train.trajectory, traj[4::5])
        held_out, train = train.subset(held_rows), train.subset(~held_rows)
    tasks = []
    for j, name in enumerate(train.muscles):
        a = model.actuator(name).id
        f0 = float(model.actuator_gainprm[a, 2])
        if not (int(model.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_MUSCLE) and f0 > 0):
            raise ValueError(f"actuator {name!r} is not a muscle with a given max force (gainprm[2] > 0)")
        st = (static or {}).get(name)
        dynamic = fit_dynamics and _dynamics(train, j) is not None
        tasks.append(_Task(name, f0, model.actuator_lengthrange[a].copy(), _start(model, a, st),
                           (train.length[:, j], train.velocity[:, j], train.activation[:, j], train.force[:, j]),
                           (held_out.length[:, j], held_out.velocity[:, j], held_out.activation[:, j],
                            held_out.force[:, j]), st, static_weight, max_nfev, model.actuator_dynprm[a, :3].copy(),
                           _dynamics(train, j) if dynamic else None, _dynamics(held_out, j) if dynamic else None,
                           1.0 if train.weight is None else train.weight[:, j]))
    fits = {f.name: f for f in map_with_progress(_fit_one, tasks, workers=processes, desc="muscle forces",
                                                 unit="muscle", progress=progress)}
    return ForceFit({t.name: fits[t.name] for t in tasks},
                    {"static_weight": static_weight, "max_nfev": max_nfev, "train_samples": len(train.length),
                     "held_out_samples": len(held_out.length),
                     "fit_dynamics": any(t.train_dynamics is not None for t in tasks)})


def _dynamics(samples: ForceSamples, j: int) -> _Dynamics | None:
    """Muscle ``j``'s activation inputs, if the samples carry their controls."""
    if samples.controls is None or samples.step is None or samples.initial_activation is None:
        return None
    return _Dynamics(samples.controls[:, :, j], samples.initial_activation[:, j], samples.trajectory, samples.step,
                     samples.timestep)
