"""Compare a converted MuJoCo model against its OpenSim original, pose by pose.

The comparison relies on the conventions of an o2m conversion:

* OpenSim ground is MuJoCo's world, related by the fixed rotation
  :data:`o2m.transforms.OSIM_TO_MJ` (``p_mj = OSIM_TO_MJ @ p_os``, ``R_mj = OSIM_TO_MJ @ R_os``).
  Nothing is fitted, so a wrong ground mapping shows up as an error.
* Every OpenSim body is a MuJoCo body of the same name whose frame (origin and orientation)
  equals the OpenSim body frame.
* Every converted OpenSim coordinate is a MuJoCo hinge or slide joint of the same name whose
  ``qpos`` equals the coordinate value (radians or metres). Dependent and locked coordinates,
  and helper joints without an OpenSim name, are driven by active MuJoCo joint equalities
  (``mjEQ_JOINT``).

:func:`pose_mujoco` puts a MuJoCo model in the pose given by joint values (resolving the joint
equalities), :func:`compare_kinematics` samples random poses in both models and returns a
:class:`KinematicsReport`, and :func:`format_table` summarises several reports.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import mujoco
import numpy as np

from o2m.errors import MissingJointError
from o2m.mj.posing import equality_residual, joint_equality_plan, joint_qpos_address, load_mjcf, pose_mujoco
from o2m.osim import runtime
from o2m.osim.names import opensim_coordinate_names
from o2m.transforms import OSIM_TO_MJ

__all__ = [
    "BodyError",
    "compare_kinematics",
    "format_table",
    "jsonable",
    "KinematicsReport",
    "rotation_angle",
    "text_table",
    "WorstPose",
]

#: Default position tolerance of :meth:`KinematicsReport.ok`, metres.
POS_TOL = 1e-4
#: Default orientation tolerance of :meth:`KinematicsReport.ok`, radians (0.05 degree).
ANG_TOL = float(np.deg2rad(0.05))
#: Default relative tolerance on the total mass of :meth:`KinematicsReport.ok`.
MASS_RTOL = 1e-6


def rotation_angle(r: np.ndarray) -> np.ndarray:
    """Angle (radians, in [0, pi]) of rotation matrices ``r`` (..., 3, 3).

    Uses ``atan2(|axial(R - R^T)|, trace - 1)``, accurate for tiny angles (unlike ``arccos``).
    """
    r = np.asarray(r, dtype=float)
    v = np.stack(
        [r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]], axis=-1
    )
    tr = r[..., 0, 0] + r[..., 1, 1] + r[..., 2, 2]
    return np.arctan2(np.linalg.norm(v, axis=-1), tr - 1.0)


# --------------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------------


@dataclass
class BodyError:
    """Error of one body frame over all poses: positions in metres, angles in radians."""

    max_pos: float
    rms_pos: float
    max_ang: float


@dataclass
class WorstPose:
    """The pose with the largest error, scored as ``max(pos / POS_TOL, ang / ANG_TOL)``.

    ``index`` is the pose number (0 is the default pose), ``body`` the worst body in that pose,
    ``pos_error`` (m) and ``ang_error`` (rad) its errors, ``values`` the OpenSim coordinate
    values of the pose (independent, dependent and locked; radians or metres).
    """

    index: int
    body: str
    pos_error: float
    ang_error: float
    values: dict[str, float]


def jsonable(x: Any) -> Any:
    """Make ``x`` JSON-safe: numpy scalars to Python, non-finite floats to None."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        f = float(x)
        return f if math.isfinite(f) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


@dataclass
class KinematicsReport:
    """Result of :func:`compare_kinematics`.

    Positions in metres, angles in radians, masses in kilograms. ``bodies`` maps each body
    present in both models to its :class:`BodyError`; ``missing_bodies`` are OpenSim bodies
    with no MuJoCo body of that name, ``extra_bodies`` MuJoCo bodies (world excluded) with no
    OpenSim body of that name. ``coordinates`` are the sampled (independent) OpenSim
    coordinates; ``dependent_coordinates`` and ``locked_coordinates`` the others.
    ``skipped_poses`` counts random poses OpenSim failed to assemble (not compared).
    """

    osim_path: str
    mjcf_path: str
    n_poses: int
    coordinates: list[str]
    bodies: dict[str, BodyError]
    max_pos_error: float
    max_ang_error: float
    com_max_error: float
    mass_opensim: float
    mass_mujoco: float
    missing_bodies: list[str] = field(default_factory=list)
    extra_bodies: list[str] = field(default_factory=list)
    dependent_coordinates: list[str] = field(default_factory=list)
    locked_coordinates: list[str] = field(default_factory=list)
    worst_pose: WorstPose | None = None
    skipped_poses: int = 0
    #: Dependent coordinates held by body equalities (given OpenSim's values) and the largest
    #: residual of those equalities at OpenSim's poses (m, or rad for a weld's rotation); not part
    #: of :meth:`ok`: OpenSim leaves its own constraints unmet where a coordinate it would move
    #: is at the end of its range.
    held_coordinates: list[str] = field(default_factory=list)
    constraint_residual: float = 0.0

    @property
    def name(self) -> str:
        """Model name: the .osim file name without its extension."""
        return os.path.splitext(os.path.basename(self.osim_path))[0]

    @property
    def mass_error(self) -> float:
        """Absolute total mass difference, kg."""
        return abs(self.mass_mujoco - self.mass_opensim)

    def ok(self, pos_tol: float = POS_TOL, ang_tol: float = ANG_TOL, mass_rtol: float = MASS_RTOL) -> bool:
        """True when every compared body and the whole-model COM (where OpenSim's model has mass)
        are within ``pos_tol`` (m),
        every orientation within ``ang_tol`` (rad), the total mass within ``mass_rtol``
        (relative), no OpenSim body is missing and at least one pose was compared."""
        return (
            self.n_poses > 0
            and not self.missing_bodies
            and self.max_pos_error <= pos_tol
            and self.max_ang_error <= ang_tol
            and self.com_max_error <= pos_tol
            and self.mass_error <= mass_rtol * max(abs(self.mass_opensim), 1.0)
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of every field (plus ``name``, ``mass_error`` and ``ok``)."""
        d = asdict(self)
        d["name"] = self.name
        d["mass_error"] = self.mass_error
        d["ok"] = self.ok()
        return jsonable(d)

    def summary(self) -> str:
        """Short readable report: per-body errors in mm and degrees, COM, masses, worst pose."""
        lines = [
            f"{self.name}: {len(self.bodies)} bodies, {self.n_poses} poses, "
            f"{len(self.coordinates)} sampled coordinates "
            f"({len(self.dependent_coordinates)} dependent, {len(self.locked_coordinates)} locked)"
            + (f", {self.skipped_poses} poses skipped (assembly failed)" if self.skipped_poses else ""),
        ]
        w = max([len("body")] + [len(b) for b in self.bodies])
        lines.append(f"  {'body':<{w}}  {'max pos mm':>11}  {'rms pos mm':>11}  {'max ang deg':>11}")
        for b, e in self.bodies.items():
            lines.append(
                f"  {b:<{w}}  {e.max_pos * 1e3:11.3g}  {e.rms_pos * 1e3:11.3g}  {np.rad2deg(e.max_ang):11.3g}"
            )
        lines.append(
            f"  max body error {self.max_pos_error * 1e3:.3g} mm, {np.rad2deg(self.max_ang_error):.3g} deg; "
            f"COM error {self.com_max_error * 1e3:.3g} mm"
        )
        lines.append(f"  mass OpenSim {self.mass_opensim:.6g} kg, MuJoCo {self.mass_mujoco:.6g} kg")
        if self.held_coordinates:
            lines.append(f"  held by body equalities (OpenSim's values): {', '.join(self.held_coordinates)}; "
                         f"equality residual at OpenSim's poses {self.constraint_residual:.3g} (OpenSim's own "
                         "may be as large where a coordinate is at the end of its range)")
        if self.missing_bodies:
            lines.append(f"  missing in MuJoCo: {', '.join(self.missing_bodies)}")
        if self.extra_bodies:
            lines.append(f"  only in MuJoCo: {', '.join(self.extra_bodies)}")
        if self.worst_pose is not None:
            wp = self.worst_pose
            lines.append(
                f"  worst pose #{wp.index}: {wp.body} {wp.pos_error * 1e3:.3g} mm, "
                f"{np.rad2deg(wp.ang_error):.3g} deg"
            )
        lines.append(f"  {'OK' if self.ok() else 'FAIL'}")
        return "\n".join(lines)


def format_table(reports: Mapping[str, KinematicsReport]) -> str:
    """Plain-text table, one row per model: bodies compared, poses, max body position error
    (mm), max orientation error (deg), COM error (mm), mass OpenSim / MuJoCo (kg), ok."""
    head = (
        "model", "bodies", "poses", "pos mm", "ang deg", "COM mm", "mass OpenSim kg", "mass MuJoCo kg", "ok"
    )
    rows = [
        (
            name,
            str(len(r.bodies)),
            str(r.n_poses),
            f"{r.max_pos_error * 1e3:.3g}",
            f"{np.rad2deg(r.max_ang_error):.3g}",
            f"{r.com_max_error * 1e3:.3g}",
            f"{r.mass_opensim:.6g}",
            f"{r.mass_mujoco:.6g}",
            "yes" if r.ok() else "NO",
        )
        for name, r in reports.items()
    ]
    return text_table(head, rows)


def text_table(head: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    """A plain-text table: first column left-aligned, the others right-aligned, a rule under ``head``."""
    widths = [max(len(row[i]) for row in [head, *rows]) for i in range(len(head))]

    def fmt(row: tuple[str, ...]) -> str:
        cells = zip(row, widths, strict=True)
        return "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(cells))

    return "\n".join([fmt(head), "  ".join("-" * w for w in widths), *(fmt(r) for r in rows)])


# --------------------------------------------------------------------------------------------
# OpenSim side
# --------------------------------------------------------------------------------------------


def _osim_rotation(rot: Any) -> np.ndarray:
    """SimTK Rotation -> numpy (3, 3)."""
    return np.array([[rot.get(i, j) for j in range(3)] for i in range(3)])


def compare_kinematics(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    *,
    n_poses: int = 200,
    seed: int = 0,
    progress: bool = False,
    assembly_accuracy: float | None = 1e-12,
    dependents: str = "mujoco",
) -> KinematicsReport:
    """Compare body frames, whole-model COM and mass of an OpenSim model and its MuJoCo twin.

    Pose 0 is the default pose of ``initSystem``; poses 1..n_poses-1 draw every independent
    OpenSim coordinate (neither locked nor dependent) uniformly in its range, from
    ``numpy.random.default_rng(seed)``. OpenSim sets those values, assembles (dependent
    coordinates follow their constraints) and realises positions; the independent values it
    then holds are written to the MuJoCo joints of the same name and :func:`pose_mujoco`
    resolves the rest. Body origins and orientations (mapped by ``OSIM_TO_MJ``) and the
    whole-model COM are compared in the MuJoCo world frame.

    ``assembly_accuracy`` overrides the OpenSim model's ``assembly_accuracy`` (None keeps the
    file's value): OpenSim's default (1e-9) leaves dependent coordinates that far from their
    constraint, which would otherwise count as conversion error. Random poses OpenSim fails
    to assemble are skipped and counted in ``skipped_poses``.

    Dependent coordinates that no joint equality drives (held by a weld, connect or tendon
    equality) take OpenSim's values, and the report gives those equalities' residual.
    ``dependents="opensim"`` instead writes every MuJoCo joint from OpenSim's own values
    (coordinates by name, CustomJoint transform axes by ``<joint>_<axis>``, e.g.
    ``knee_r_translation1``) and resolves no equality: it measures the converted structure
    alone, separating it from the error of the equalities' polynomial fits.

    Raises :class:`o2m.errors.ModelFileError` if OpenSim cannot load ``osim_path``,
    :class:`ValidationError` if MuJoCo cannot load ``mjcf_path`` (meshes included) and
    :class:`MissingJointError` if an independent coordinate has no MuJoCo hinge/slide joint.
    """
    if n_poses < 1:
        raise ValueError("n_poses must be at least 1")
    from tqdm.auto import tqdm

    osim_path, mjcf_path = os.fspath(osim_path), os.fspath(mjcf_path)
    os_model, init_state = runtime.load_model(osim_path, assembly_accuracy)
    mj_model = load_mjcf(mjcf_path)
    mj_data = mujoco.MjData(mj_model)

    # Coordinates.
    opensim = runtime.opensim()

    coord_set = os_model.getCoordinateSet()
    coords = [coord_set.get(i) for i in range(coord_set.getSize())]
    mj_names = opensim_coordinate_names(os_model)
    all_names = [mj_names[c.getAbsolutePathString()] for c in coords]
    locked = [n for n, c in zip(all_names, coords, strict=True) if runtime.is_held(c, init_state)]
    dependent = [n for n, c in zip(all_names, coords, strict=True)
                 if not runtime.is_held(c, init_state) and c.isDependent(init_state)]
    not_sampled = set(locked) | set(dependent)
    indep = [c for n, c in zip(all_names, coords, strict=True) if n not in not_sampled]
    indep_names = [n for n in all_names if n not in not_sampled]

    missing_joints = []
    for name in indep_names:
        try:
            joint_qpos_address(mj_model, name)
        except KeyError:
            missing_joints.append(name)
    if missing_joints:
        raise MissingJointError(missing_joints, mjcf_path)

    # Bodies.
    os_bodies = {b.getName(): b for b in os_model.getBodyList()}  # the BodySet's and any in <components>
    mj_bodies = {
        mujoco.mj_id2name(mj_model, mujoco.mjtObj.mjOBJ_BODY, i) or f"<body {i}>": i
        for i in range(1, mj_model.nbody)
    }
    common = [b for b in os_bodies if b in mj_bodies]
    missing_bodies = [b for b in os_bodies if b not in mj_bodies]
    extra_bodies = [b for b in mj_bodies if b not in os_bodies]
    mj_ids = np.array([mj_bodies[b] for b in common], dtype=int)
    os_body_objs = [os_bodies[b] for b in common]

    mass_os = float(sum(b.getMass() for b in os_bodies.values()))
    # the mass gravity acts on: o2m's path-point carriers on world-welded bodies carry mass for
    # MuJoCo's constraint solver with their weight cancelled (gravcomp), and move nothing else
    weight = mj_model.body_mass * (1.0 - mj_model.body_gravcomp)  # (nbody,) kg
    mass_mj = float(weight.sum())

    # Poses.
    rng = np.random.default_rng(seed)
    bounds = np.array([runtime.sample_bounds(c) for c in indep], dtype=float).reshape(-1, 2)
    samples = rng.uniform(bounds[:, 0], bounds[:, 1], size=(max(n_poses - 1, 0), len(indep)))
    if dependents not in ("mujoco", "opensim"):
        raise ValueError(f"dependents must be 'mujoco' or 'opensim', not {dependents!r}")
    plan = joint_equality_plan(mj_model) if dependents == "mujoco" else []
    # dependent coordinates no coupler drives are held by body equalities (weld, connect, tendon
    # length), which MuJoCo meets only as it steps: they take OpenSim's values, and the
    # equalities' residual at those poses measures the conversion instead (a coupler's dependent
    # must follow its joint equality: a missing one is an error to find)
    coupled = _coupler_dependents(os_model)
    held = [n for n in dependent if n not in coupled and _has_scalar_joint(mj_model, n)] \
        if dependents == "mujoco" else []
    residual = 0.0
    axis_values = _transform_axes_by_mujoco_name(os_model, mj_model) if dependents == "opensim" else {}

    nb = len(common)
    sq_sum = np.zeros(nb)
    max_pos = np.zeros(nb)
    max_ang = np.zeros(nb)
    com_max = 0.0
    n_done = 0
    skipped = 0
    worst: WorstPose | None = None
    worst_score = -1.0

    for k in tqdm(range(n_poses), disable=not progress, desc=f"poses {os.path.basename(osim_path)}"):
        if k == 0:
            state = init_state
        else:
            state = opensim.State(init_state)
            for c, v in zip(indep, samples[k - 1], strict=True):
                c.setValue(state, float(v), False)
            try:
                os_model.assemble(state)
            except Exception:  # assembly failure: skip this pose
                skipped += 1
                continue
        os_model.realizePosition(state)
        values = {name: float(c.getValue(state)) for name, c in zip(all_names, coords, strict=True)}

        if dependents == "mujoco":
            pose_mujoco(mj_model, mj_data, {n: values[n] for n in indep_names + held}, plan=plan)
            if held:
                residual = max(residual, equality_residual(mj_model, mj_data))
        else:
            given = {n: v for n, v in values.items() if _has_scalar_joint(mj_model, n)}
            given.update({n: float(ax.getValue(state)) for n, ax in axis_values.items()})
            pose_mujoco(mj_model, mj_data, given, plan=plan)

        pos_os = np.empty((nb, 3))
        rot_os = np.empty((nb, 3, 3))
        for i, body in enumerate(os_body_objs):
            xf = body.getTransformInGround(state)
            pos_os[i] = xf.p().to_numpy()
            rot_os[i] = _osim_rotation(xf.R())
        pos_os = pos_os @ OSIM_TO_MJ.T
        rot_os = OSIM_TO_MJ @ rot_os
        pos_mj = mj_data.xpos[mj_ids]
        rot_mj = mj_data.xmat[mj_ids].reshape(nb, 3, 3)

        dpos = np.linalg.norm(pos_mj - pos_os, axis=1)
        dang = rotation_angle(np.swapaxes(rot_mj, 1, 2) @ rot_os)
        com_os = OSIM_TO_MJ @ os_model.calcMassCenterPosition(state).to_numpy()
        com_mj = (weight[:, None] * mj_data.xipos).sum(axis=0) / max(mass_mj, 1e-300)  # as the mass
        # a massless model (WristModel) has no centre of mass to compare
        com_err = float(np.linalg.norm(com_mj - com_os)) if mass_os > 0 else 0.0

        sq_sum += dpos**2
        np.maximum(max_pos, dpos, out=max_pos)
        np.maximum(max_ang, dang, out=max_ang)
        com_max = max(com_max, com_err)
        n_done += 1

        if nb:
            scores = np.maximum(dpos / POS_TOL, dang / ANG_TOL)
            i = int(np.argmax(scores))
            if scores[i] > worst_score:
                worst_score = float(scores[i])
                worst = WorstPose(k, common[i], float(dpos[i]), float(dang[i]), values)

    rms = np.sqrt(sq_sum / max(n_done, 1))
    bodies = {b: BodyError(float(max_pos[i]), float(rms[i]), float(max_ang[i])) for i, b in enumerate(common)}
    return KinematicsReport(
        osim_path=osim_path,
        mjcf_path=mjcf_path,
        n_poses=n_done,
        coordinates=indep_names,
        bodies=bodies,
        max_pos_error=float(max_pos.max()) if nb else 0.0,
        max_ang_error=float(max_ang.max()) if nb else 0.0,
        com_max_error=com_max,
        mass_opensim=mass_os,
        mass_mujoco=mass_mj,
        missing_bodies=missing_bodies,
        extra_bodies=extra_bodies,
        dependent_coordinates=dependent,
        locked_coordinates=locked,
        held_coordinates=held,
        constraint_residual=residual,
        worst_pose=worst,
        skipped_poses=skipped,
    )


def _coupler_dependents(os_model: Any) -> set[str]:
    """Names of the dependent coordinates of the model's enforced CoordinateCouplerConstraints."""
    opensim = runtime.opensim()
    cs = os_model.getConstraintSet()
    out = set()
    for i in range(cs.getSize()):
        c = opensim.CoordinateCouplerConstraint.safeDownCast(cs.get(i))
        if c is not None and c.get_isEnforced():
            out.add(c.getDependentCoordinateName())
    return out


def _has_scalar_joint(model: mujoco.MjModel, name: str) -> bool:
    try:
        joint_qpos_address(model, name)
    except KeyError:
        return False
    return True


def _transform_axes_by_mujoco_name(os_model: Any, mj_model: mujoco.MjModel) -> dict[str, Any]:
    """OpenSim TransformAxis objects keyed by the MuJoCo joint named ``<joint>_<axis>``."""
    opensim = runtime.opensim()

    out: dict[str, Any] = {}
    joint_set = os_model.getJointSet()
    for i in range(joint_set.getSize()):
        cj = opensim.CustomJoint.safeDownCast(joint_set.get(i))
        if cj is None:
            continue
        st = cj.getSpatialTransform()
        for k in range(6):
            ax = st.getTransformAxis(k)
            name = f"{cj.getName()}_{ax.getName()}"
            if _has_scalar_joint(mj_model, name):
                out[name] = ax
    return out
