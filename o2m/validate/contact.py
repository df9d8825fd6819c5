"""Contact against OpenSim: a ball dropped on a half space, and a ball sliding over it.

:func:`write_ball_model` writes a small OpenSim model: a ball (a Body on a PlanarJoint whose
rotation is locked, so it translates in the vertical x-y plane of OpenSim's Y-up ground) with a
ContactSphere, a ContactHalfSpace on ground (the plane y = 0) and one HuntCrossleyForce between
them. :func:`opensim_trace` simulates it in OpenSim 4.6 (:func:`o2m.osim.simulate.simulate`),
:func:`mujoco_trace` simulates the converted MJCF in MuJoCo at the model's timestep; both give a
:class:`Trace` of the ball's centre (m) and horizontal speed (m/s).

* **Drop** (:func:`drop_metrics`): released at rest from a height, the time of first contact
  (s), the peak penetration (m), the contact's duration (s) and the rebound height (the sphere's
  lowest point at its highest after the first contact, m); :func:`compare_drop` adds the
  coefficient of restitution √(rebound height / drop height).
* **Slide** (:func:`slide_metrics`): set down on the plane with a horizontal speed, where it
  stops (m, when its speed first falls below :data:`STOPPED` of the start) and when (s).

:func:`compare_drop` and :func:`compare_slide` run both simulators and return a
:class:`ContactComparison` with each number in both and their differences.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from o2m.osim import runtime
from o2m.osim.simulate import IntegratorSettings, simulate

__all__ = ["STOPPED", "BallModel", "ContactComparison", "Trace", "compare_drop", "compare_slide", "drop_metrics",
           "mujoco_trace", "opensim_trace", "slide_metrics", "write_ball_model"]

#: A sliding ball has stopped when its speed is below this fraction of its starting speed.
STOPPED = 0.01
#: OpenSim's integrator for contact: tight accuracy (the Hunt-Crossley force is stiff).
OPENSIM_SETTINGS = IntegratorSettings(method="RungeKuttaMerson", accuracy=1e-8, min_step=1e-9, max_step=1e-4)
#: Sample interval (s) of OpenSim's trace.
OPENSIM_SAMPLE = 1e-4
_JOINT = "ball_joint"


@dataclass(frozen=True)
class BallModel:
    """The ball: mass (kg), radius (m) and the contact parameters of ball and floor (one
    ContactParameters naming both): stiffness (N/m²), dissipation (s/m), friction coefficients,
    viscous friction (s/m) and the force's transition velocity (m/s). ``smooth``: a
    SmoothSphereHalfSpaceForce with these parameters and its smoothing (``hertz_smoothing`` 1/m,
    ``hunt_crossley_smoothing`` s/m, ``constant_contact_force`` m²) instead of a HuntCrossleyForce."""

    mass: float = 1.0
    radius: float = 0.05
    stiffness: float = 1e7
    dissipation: float = 0.5
    static_friction: float = 0.8
    dynamic_friction: float = 0.6
    viscous_friction: float = 0.0
    transition_velocity: float = 0.1
    smooth: bool = False
    hertz_smoothing: float = 300.0
    hunt_crossley_smoothing: float = 50.0
    constant_contact_force: float = 1e-5


def write_ball_model(path: str | Path, ball: BallModel = BallModel()) -> Path:  # noqa: B008 (frozen)
    """Write the ball-on-floor OpenSim model to ``path`` (.osim) with OpenSim's own API."""
    osim = runtime.opensim()
    model = osim.Model()
    model.setName("ball_contact")
    model.setGravity(osim.Vec3(0, -9.80665, 0))
    body = osim.Body("ball", ball.mass, osim.Vec3(0), osim.Inertia(0.4 * ball.mass * ball.radius ** 2))
    model.addBody(body)
    joint = osim.PlanarJoint(_JOINT, model.getGround(), body)
    for i, name in enumerate(("ball_rz", "ball_tx", "ball_ty")):
        joint.upd_coordinates(i).setName(name)
    joint.upd_coordinates(0).setDefaultLocked(True)
    model.addJoint(joint)
    floor = osim.ContactHalfSpace(osim.Vec3(0), osim.Vec3(0, 0, -math.pi / 2), model.getGround(), "floor")
    sphere = osim.ContactSphere(ball.radius, osim.Vec3(0), body, "ball_sphere")
    model.addContactGeometry(floor)
    model.addContactGeometry(sphere)
    model.addForce(_smooth_force(osim, ball, sphere, floor) if ball.smooth else _hunt_crossley(osim, ball))
    model.finalizeConnections()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    model.printToXML(str(path))
    return path


def _hunt_crossley(osim, ball: BallModel):
    force = osim.HuntCrossleyForce()
    force.setName("contact")
    force.addGeometry("floor")
    force.addGeometry("ball_sphere")
    force.setStiffness(ball.stiffness)
    force.setDissipation(ball.dissipation)
    force.setStaticFriction(ball.static_friction)
    force.setDynamicFriction(ball.dynamic_friction)
    force.setViscousFriction(ball.viscous_friction)
    force.setTransitionVelocity(ball.transition_velocity)
    return force


def _smooth_force(osim, ball: BallModel, sphere, floor):
    force = osim.SmoothSphereHalfSpaceForce("contact", sphere, floor)
    for prop in ("stiffness", "dissipation", "static_friction", "dynamic_friction", "viscous_friction",
                 "transition_velocity", "hertz_smoothing", "hunt_crossley_smoothing", "constant_contact_force"):
        getattr(force, f"set_{prop}")(getattr(ball, prop))
    return force


@dataclass
class Trace:
    """The ball over time: ``times`` (s), centre ``x`` and ``y`` (m, OpenSim ground; y up) and
    horizontal speed ``vx`` (m/s)."""

    times: np.ndarray
    x: np.ndarray
    y: np.ndarray
    vx: np.ndarray


def opensim_trace(osim: str | Path, height: float, speed: float = 0.0, duration: float = 1.0) -> Trace:
    """OpenSim's ball released with its centre at ``height`` (m) and horizontal ``speed`` (m/s)."""
    times = np.arange(0.0, duration + 0.5 * OPENSIM_SAMPLE, OPENSIM_SAMPLE)
    state = {f"/jointset/{_JOINT}/ball_ty/value": height, f"/jointset/{_JOINT}/ball_tx/speed": speed}
    run = simulate(osim, times, np.zeros((len(times), 0)), [], initial_state=state, settings=OPENSIM_SETTINGS)
    if not run.ok:
        raise RuntimeError(f"OpenSim's ball simulation {run.status}: {run.reason}")
    col = {n: i for i, n in enumerate(run.coordinate_names)}
    return Trace(run.times, run.coordinates[:, col["ball_tx"]], run.coordinates[:, col["ball_ty"]],
                 run.speeds[:, col["ball_tx"]])


def mujoco_trace(xml: str | Path, height: float, speed: float = 0.0, duration: float = 1.0,
                 timestep: float | None = None) -> Trace:
    """MuJoCo's ball (the converted model, at its own timestep unless ``timestep`` (s) is given)."""
    model = mujoco.MjModel.from_xml_path(str(xml))
    if timestep is not None:
        model.opt.timestep = timestep
    data = mujoco.MjData(model)
    tx, ty = model.joint("ball_tx"), model.joint("ball_ty")
    data.qpos[ty.qposadr[0]] = height
    data.qvel[tx.dofadr[0]] = speed
    n = int(round(duration / model.opt.timestep))
    out = np.zeros((n + 1, 3))
    out[0] = data.qpos[tx.qposadr[0]], data.qpos[ty.qposadr[0]], data.qvel[tx.dofadr[0]]
    for k in range(1, n + 1):
        mujoco.mj_step(model, data)
        out[k] = data.qpos[tx.qposadr[0]], data.qpos[ty.qposadr[0]], data.qvel[tx.dofadr[0]]
    return Trace(np.arange(n + 1) * model.opt.timestep, out[:, 0], out[:, 1], out[:, 2])


def _crossing(t: np.ndarray, f: np.ndarray, i: int) -> float:
    """Time f crosses zero between samples i-1 and i (linear)."""
    return float(t[i - 1] + (t[i] - t[i - 1]) * f[i - 1] / (f[i - 1] - f[i]))


def drop_metrics(trace: Trace, radius: float) -> dict[str, float]:
    """Time of first contact (s), peak penetration (m), contact duration (s), rebound height (m).
    A ball that never leaves the floor (gravity holding it on a damped contact) has duration
    ``inf`` and rebound height 0."""
    pen = radius - trace.y
    inside = np.flatnonzero(pen > 0)
    if not inside.size:
        raise ValueError("the ball never touches the floor")
    i0 = int(inside[0])
    t_in = _crossing(trace.times, pen, i0) if i0 > 0 else 0.0
    after = np.flatnonzero(pen[i0:] <= 0)
    if not after.size:
        return {"contact_time": t_in, "peak_penetration": float(np.max(pen[i0:])), "contact_duration": math.inf,
                "rebound_height": 0.0}
    i1 = i0 + int(after[0])
    t_out = _crossing(trace.times, pen, i1)
    back = np.flatnonzero(pen[i1:] > 0)
    end = i1 + int(back[0]) if back.size else len(pen)
    return {"contact_time": t_in, "peak_penetration": float(np.max(pen[i0:i1])), "contact_duration": t_out - t_in,
            "rebound_height": float(np.max(-pen[i1:end]))}


def slide_metrics(trace: Trace) -> dict[str, float]:
    """Where (m from the start) and when (s) the ball's speed first falls below :data:`STOPPED` of its start."""
    v0 = abs(trace.vx[0])
    slow = np.flatnonzero(np.abs(trace.vx) < STOPPED * v0)
    k = int(slow[0]) if slow.size else len(trace.vx) - 1
    return {"stop_distance": float(trace.x[k] - trace.x[0]), "stop_time": float(trace.times[k])}


@dataclass
class ContactComparison:
    """One experiment in both simulators: each metric in OpenSim and MuJoCo (SI units)."""

    experiment: str
    opensim: dict[str, float]
    mujoco: dict[str, float]
    extra: dict[str, float]

    def error(self, key: str) -> float:
        return self.mujoco[key] - self.opensim[key]

    def relative(self, key: str) -> float:
        return self.error(key) / abs(self.opensim[key])

    def summary(self) -> str:
        lines = [self.experiment]
        for k, v in self.opensim.items():
            lines.append(f"  {k:18s} OpenSim {v:10.5g}  MuJoCo {self.mujoco[k]:10.5g}  error {self.error(k):+10.3g} "
                         f"({100 * self.relative(k):+.1f} %)")
        lines.extend(f"  {k:18s} {v:.4g}" for k, v in self.extra.items())
        return "\n".join(lines)


def compare_drop(osim: str | Path, xml: str | Path, ball: BallModel, drop: float, duration: float = 1.0,
                 timestep: float | None = None) -> ContactComparison:
    """The ball released at rest with its lowest point ``drop`` (m) above the floor."""
    h = ball.radius + drop
    a = drop_metrics(opensim_trace(osim, h, 0.0, duration), ball.radius)
    b = drop_metrics(mujoco_trace(xml, h, 0.0, duration, timestep), ball.radius)
    for m in (a, b):  # the rebound's share of the impact speed (free flight both ways)
        m["restitution"] = math.sqrt(m["rebound_height"] / drop)
    return ContactComparison(f"drop from {drop:g} m (impact at {math.sqrt(2 * 9.80665 * drop):.3g} m/s)", a, b, {})


def compare_slide(osim: str | Path, xml: str | Path, ball: BallModel, speed: float, duration: float = 1.0,
                  timestep: float | None = None, height: float | None = None) -> ContactComparison:
    """The ball set down with its centre at ``height`` (m; default: touching the floor) with
    horizontal ``speed`` (m/s). A smooth force already pushes at contact: set it down where it rests."""
    h = ball.radius if height is None else height
    ta = opensim_trace(osim, h, speed, duration)
    tb = mujoco_trace(xml, h, speed, duration, timestep)
    vb = np.interp(ta.times, tb.times, tb.vx)
    extra = {"speed error max (m/s)": float(np.max(np.abs(vb - ta.vx))),
             "speed error rms (m/s)": float(np.sqrt(np.mean((vb - ta.vx) ** 2)))}
    return ContactComparison(f"slide at {speed:g} m/s", slide_metrics(ta), slide_metrics(tb), extra)
