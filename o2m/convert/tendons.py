"""Building MuJoCo spatial tendons and their actuators from OpenSim paths.

Each path becomes a spatial tendon through sites, one handler per OpenSim element family:

* PathPoints and MovingPathPoints: sites, a moving point's on a carrier body
  (:mod:`o2m.convert.carriers`);
* ConditionalPathPoints: a small wrap sphere with a moving side site (:mod:`o2m.convert.conditional`);
* wrap objects: a wrap geom per path with a side site (:mod:`o2m.convert.wraps`);
* same-body segments next to a MovingPathPoint: kept, or held in a pulley branch
  (``path_forces``, :mod:`o2m.convert.pathforces`).

Each muscle becomes a MuJoCo muscle actuator on its tendon, named as the muscle. Lengths are
metres, angles radians; OpenSim's ground (Y-up) is MuJoCo's world (Z-up).
"""

from __future__ import annotations

import mujoco
import numpy as np

from o2m.convert.builder import MjcfBuilder
from o2m.convert.carriers import CARRIER_AXIS_TOLERANCE, Carriers
from o2m.convert.conditional import GEOM_ROLES, conditional_geom, conditional_roles
from o2m.convert.force_context import _applies_force
from o2m.convert.pathforces import PathForces
from o2m.convert.pathpoints import PathContext
from o2m.convert.wraps import PathGeom, WrapGeoms
from o2m.osim.paths import MUSCLE_TYPES, Path, WrapObject
from o2m.transforms import Transform

#: MuJoCo actuator group of the muscles OpenSim's model disables (``appliesForce`` false): the
#: model disables the group (``actuatorgroupdisable``), so they apply no force until enabled.
DISABLED_MUSCLE_GROUP = 5


class TendonBuilder:
    """Adds the paths of a skeleton to an :class:`MjcfBuilder`'s spec."""

    def __init__(self, builder: MjcfBuilder, wraps: dict[str, WrapObject], path_forces: str = "auto",
                 carrier_tolerance: float = CARRIER_AXIS_TOLERANCE):
        self.ctx = PathContext(builder)
        self.forces = PathForces(self.ctx, path_forces)
        self.b = builder
        self.spec = builder.spec
        self.carriers = Carriers(self.ctx, carrier_tolerance)
        self.wrap_geoms = WrapGeoms(self.ctx, wraps)
        #: One :class:`~o2m.convert.pathforces.PathForceRecord` per path with same-body
        #: MovingPathPoint segments.
        self.path_forces = self.forces.records
        #: Paths whose same-body segments are held ("opensim"): name -> {"pairs": [(OpenSim point,
        #: point)], "length": held length (m)}, for :mod:`o2m.convert.wrapfit`'s targets.
        self.held = self.forces.held
        #: Exact attribute values of the geoms added here, by ("geom", name)
        #: (see :func:`o2m.convert.wraps.restore_geom_precision`).
        self.exact = self.ctx.exact
        #: Every wrap geom of every tendon, in the order added.
        self.path_geoms: list[PathGeom] = []

    def weigh_static_carriers(self, model: mujoco.MjModel) -> list[str]:
        """Give the carriers on bodies welded to the world some mass (:meth:`Carriers.weigh_static`)."""
        return self.carriers.weigh_static(model)

    def add_path(self, path: Path) -> None:
        """Add ``path``'s tendon: its sites, the geoms it wraps, its held branch, its actuator."""
        roles = conditional_roles(self.ctx, path)
        site_point = [k for k, r in enumerate(roles) if r == "site"]
        sites_ground = np.array([(self.b.ground_frames[p.body] @ Transform(pos=p.location)).pos for p in path.points])
        planned = self._plan_segments(path, roles, sites_ground)
        dropped, held_length = self.forces.plan(path, roles, site_point, planned)
        sites = [self.carriers.add_point(path, path.points[k]) for k in site_point]
        on_segment = self._segment_geoms(path, roles, planned, dropped, sites, sites_ground)
        branches: list[list[int]] = [[0]]
        for i in range(len(sites) - 1):
            if i in dropped:
                branches.append([i + 1])
            else:
                branches[-1].append(i + 1)
        runs = [[sites[i] for i in br] for br in branches if len(br) > 1]
        if dropped:
            first = dropped[0]
            runs.append(self.forces.held_branch(path, path.points[site_point[first]],
                                                path.points[site_point[first + 1]], held_length))
        self._add_tendon(path, sites, runs, on_segment)

    def _plan_segments(self, path: Path, roles: list[str], sites_ground: np.ndarray) -> dict[int, tuple]:
        """What each site segment of ``path`` wraps, decided before any geom is made: site segment
        -> ("conditional", point) or ("wrap", WrapObject, path segment). MuJoCo wraps one geom per
        segment: a wrap object on a segment that already wraps something is left out (noted)."""
        site_of_point: list[int] = []  # for each point, the index of the last site at or before it
        for role in roles:
            site_of_point.append((site_of_point[-1] if site_of_point else -1) + (role == "site"))
        planned: dict[int, tuple] = {}
        for k, role in enumerate(roles):
            if role in GEOM_ROLES:
                planned[site_of_point[k]] = ("conditional", k)
        for seg, wrap in self.wrap_geoms.place(path, sites_ground):
            sseg = site_of_point[seg]
            if sseg in planned:
                kind, other = planned[sseg][0], planned[sseg][1]
                what = (f"ConditionalPathPoint '{path.points[other].name}'" if kind == "conditional"
                        else f"'{other.name}'")
                self.b.result.notes.append(f"{path.owner}: wrap object '{wrap.name}' left out (its path segment "
                                           f"already wraps {what}; MuJoCo wraps one geom there)")
                continue
            planned[sseg] = ("wrap", wrap, seg)
        return planned

    def _segment_geoms(self, path: Path, roles: list[str], planned: dict[int, tuple], dropped: list[int],
                       sites: list[str], sites_ground: np.ndarray) -> dict[int, tuple[str, str]]:
        """Add the geoms ``planned`` (conditional points first) but those on ``dropped`` (held)
        segments; returns each site segment's (geom, side site)."""
        on_segment: dict[int, tuple[str, str]] = {}
        for sseg, item in sorted(planned.items(), key=lambda kv: (kv[1][0] != "conditional", kv[0])):
            if sseg in dropped:
                self.b.result.notes.append(f"{path.owner}: {item[0]} on the held segment "
                                           f"{sites[sseg]}-{sites[sseg + 1]} left out with it")
                continue
            if item[0] == "conditional":
                on_segment[sseg] = conditional_geom(self.ctx, self.carriers, path, item[1], roles)
                continue
            wrap, seg = item[1], item[2]
            geom = self.wrap_geoms.geom(wrap, sites_ground[seg], sites_ground[seg + 1])
            if geom is None:
                continue
            side = self.wrap_geoms.side_site(wrap, geom, sites_ground[seg], sites_ground[seg + 1])
            on_segment[sseg] = (geom, side)
            self.path_geoms.append(PathGeom(path.owner, geom, side, "Wrap" + wrap.kind.capitalize(), wrap.name,
                                            wrap.body, self.wrap_geoms.geom_frames[geom][1],
                                            self.wrap_geoms.alternatives.get(geom)))
        return on_segment

    def _add_tendon(self, path: Path, sites: list[str], runs: list[list[str]],
                    on_segment: dict[int, tuple[str, str]]) -> None:
        """The tendon through ``runs`` of sites (pulley branches after the first), wrapping the
        geoms ``on_segment``, and the actuator of ``path``'s muscle."""
        tendon = self.spec.add_tendon(name=path.owner)
        index = {name: i for i, name in enumerate(sites)}
        for r, run in enumerate(runs):
            if r:
                tendon.wrap_pulley(1.0)
            for k, site in enumerate(run):
                tendon.wrap_site(site)
                i = index.get(site)
                if k + 1 < len(run) and i is not None and i in on_segment:
                    tendon.wrap_geom(*on_segment[i])
        if path.owner_type in MUSCLE_TYPES:
            act = self.spec.add_actuator(name=path.owner, trntype=mujoco.mjtTrn.mjTRN_TENDON, target=path.owner)
            fmax = float(path.element.findtext("max_isometric_force") or 1000.0)
            act.set_to_muscle(timeconst=[0.01, 0.04], tausmooth=0.0, force=fmax)
            if not _applies_force(path.element):
                act.group = DISABLED_MUSCLE_GROUP
                self.spec.option.disableactuator |= 1 << DISABLED_MUSCLE_GROUP
                self.b.result.notes.append(
                    f"{path.owner_type} '{path.owner}' is disabled in OpenSim (appliesForce false): its actuator is "
                    f"in group {DISABLED_MUSCLE_GROUP}, which the model disables (option actuatorgroupdisable)")


def add_paths(builder: MjcfBuilder, paths: list[Path], wraps: dict[str, WrapObject], *,
              path_forces: str = "auto", carrier_tolerance: float = CARRIER_AXIS_TOLERANCE) -> TendonBuilder:
    """Add every path (tendon, sites, wrap geoms, actuator) to ``builder``'s spec; returns the
    :class:`TendonBuilder` (its ``path_geoms``, ``exact`` geom values, ``path_forces`` records and
    ``held`` segments). ``path_forces``: see :mod:`o2m.convert.pathforces`; ``carrier_tolerance``
    (m): see :class:`o2m.convert.carriers.Carriers`."""
    tb = TendonBuilder(builder, wraps, path_forces, carrier_tolerance)
    tb.carriers.plan(paths)
    for path in paths:
        tb.add_path(path)
    return tb


def tendon_length_ranges(model: mujoco.MjModel, coordinates: dict[str, tuple[float, float]], *,
                         n_poses: int = 500, seed: int = 0) -> np.ndarray:
    """(ntendon, 2) smallest and largest tendon lengths (m) over random poses.

    ``coordinates`` maps each independent coordinate joint to the range it is sampled in; every
    other joint follows the model's equalities. The default pose and the range corners of one
    coordinate at a time are included, so extremes at the limits are not missed.
    """
    from o2m.mj.posing import joint_equality_plan, pose_mujoco

    data = mujoco.MjData(model)
    plan = joint_equality_plan(model)
    rng = np.random.default_rng(seed)
    names = list(coordinates)
    lo = np.array([coordinates[n][0] for n in names])
    hi = np.array([coordinates[n][1] for n in names])
    defaults = np.array([model.qpos0[model.joint(n).qposadr[0]] for n in names])
    poses = [defaults] + [np.where(np.arange(len(names)) == i, v, defaults)
                          for i in range(len(names)) for v in (lo[i], hi[i])]
    poses += list(rng.uniform(lo, hi, size=(n_poses, len(names))))
    out = np.full((model.ntendon, 2), [np.inf, -np.inf])
    for q in poses:
        pose_mujoco(model, data, dict(zip(names, q, strict=True)), plan=plan)
        mujoco.mj_tendon(model, data)
        out[:, 0] = np.minimum(out[:, 0], data.ten_length)
        out[:, 1] = np.maximum(out[:, 1], data.ten_length)
    return out
