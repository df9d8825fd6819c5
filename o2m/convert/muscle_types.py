"""What each OpenSim muscle type o2m maps says about its dynamics: activation time constants
and the force-velocity curve, read from the muscle through OpenSim.

Times are seconds; velocities are normalized fiber velocities (fiber velocity / (max contraction
velocity * optimal fiber length), negative when shortening).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from o2m.osim import runtime

__all__ = ["FIBER_DAMPED", "MUJOCO_DEFAULTS", "SUPPORTED_MUSCLES", "fiber_damping"]

#: OpenSim muscle types :func:`~o2m.convert.muscles.fit_muscles` maps.
SUPPORTED_MUSCLES = (
    "Thelen2003Muscle",
    "Millard2012EquilibriumMuscle",
    "Millard2012AccelerationMuscle",
    "Schutte1993Muscle_Deprecated",
    "DeGrooteFregly2016Muscle",
    "RigidTendonMuscle",
    "Delp1990Muscle_Deprecated",
    "Thelen2003Muscle_Deprecated",
    "MeyerFregly2016Muscle",
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


def _prop(obj, name: str, default: float | None = None) -> float:
    """A double property of an OpenSim object, by name (works for any concrete type)."""
    osim = runtime.opensim()
    if not obj.hasProperty(name):
        if default is None:
            raise KeyError(name)
        return default
    return float(osim.PropertyHelper.getValueDouble(obj.getPropertyByName(name)))


def _bool_prop(obj, name: str) -> bool:
    osim = runtime.opensim()
    if not obj.hasProperty(name):
        return False
    return bool(osim.PropertyHelper.getValueBool(obj.getPropertyByName(name)))


def _downcast(muscle, type_name: str):
    osim = runtime.opensim()
    cls = getattr(osim, type_name, None)
    return cls.safeDownCast(muscle) if cls is not None and hasattr(cls, "safeDownCast") else muscle


def _activation_times(m, type_name: str, notes: list[str]) -> tuple[float, float]:
    """MuJoCo (activation, deactivation) time constants for an OpenSim muscle."""
    if type_name in ("Thelen2003Muscle", "Millard2012EquilibriumMuscle"):
        ta, td = _prop(m, "activation_time_constant"), _prop(m, "deactivation_time_constant")
        _note_ignored_activation(m, notes)
        return ta, td
    if type_name == "Millard2012AccelerationMuscle":
        model = _downcast(m, type_name).get_MuscleFirstOrderActivationDynamicModel()
        return _prop(model, "activation_time_constant"), _prop(model, "deactivation_time_constant")
    if type_name in ("Schutte1993Muscle_Deprecated", "Delp1990Muscle_Deprecated"):
        ts, a1, a2 = _prop(m, "time_scale"), _prop(m, "activation1"), _prop(m, "activation2")
        ta, td, rms, rms_step = _schutte_time_constants(ts, a1, a2)
        notes.append(f"Schutte activation dynamics (da/dt = (u - a)(a1 u + a2)/ts rising, (u - a) a2/ts falling) "
                     f"mapped to MuJoCo's time constants {ta:.4g}/{td:.4g} s, fitted to follow it under random "
                     f"excitations: activation RMS error {rms:.4f} (matching a full step's rise and decay "
                     f"instead: {rms_step:.4f})")
        return ta, td
    if type_name in ("Thelen2003Muscle_Deprecated", "MeyerFregly2016Muscle", "DeGrooteFregly2016Muscle"):
        return _other_activation_law(m, type_name, notes)
    notes.append("RigidTendonMuscle has no activation dynamics; MuJoCo's default time constants 0.01/0.04 s")
    return MUJOCO_DEFAULTS["timeconst"]


def _note_ignored_activation(m, notes: list[str]) -> None:
    if _bool_prop(m, "ignore_activation_dynamics"):
        notes.append("OpenSim ignores activation dynamics (activation = excitation); MuJoCo's "
                     "muscle filters with the muscle's time constants")


#: DeGrooteFregly2016Muscle's and MeyerFregly2016Muscle's tanh steepness where their
#: ``activation_dynamics_smoothing`` property is missing (the constant of the versions without it).
DEFAULT_ACTIVATION_SMOOTHING = 0.1


def _other_activation_law(m, type_name: str, notes: list[str]) -> tuple[float, float]:
    """Time constants (s) fitted to the activation laws that are not MuJoCo's: Thelen2003Muscle_Deprecated's
    constant time constants and the tanh blend of the two rates of DeGrooteFregly2016Muscle and
    MeyerFregly2016Muscle (MuJoCo switches between them where the excitation passes the activation;
    their default smoothing 0.1 keeps both rates near their mean)."""
    ta, td = _prop(m, "activation_time_constant"), _prop(m, "deactivation_time_constant")
    if type_name == "Thelen2003Muscle_Deprecated":
        law, params = "constant", (ta, td)
        what = "constant time constants (da/dt = (u - a)/ta rising, (u - a)/td falling)"
    else:
        _note_ignored_activation(m, notes)
        b = _prop(m, "activation_dynamics_smoothing", DEFAULT_ACTIVATION_SMOOTHING)
        law, params = "tanh_blend", (ta, td, b)
        what = (f"rates blended by 0.5 tanh({b:.3g} (u - a)) (da/dt = (u - a)[(f + 0.5)/(ta z) + (0.5 - f) z/td], "
                "z = 0.5 + 1.5 a)")
    t_act, t_deact, rms, rms_own = _fitted_time_constants(law, params, (ta, td))
    notes.append(f"{type_name} activation dynamics, {what}, mapped to MuJoCo's time constants {t_act:.4g}/"
                 f"{t_deact:.4g} s, fitted to follow it under random excitations: activation RMS error {rms:.4f} "
                 f"(the muscle's own {ta:.4g}/{td:.4g} s instead: {rms_own:.4f})")
    return t_act, t_deact


#: Excitations the activation mappings are fitted on: slow sines as in the paper's sets, up to
#: this frequency (Hz), active with probability 1.
ACTIVATION_FIT_SETS, ACTIVATION_FIT_MAX_FREQ = 24, 3.0


def _activation_rate(law: str, params: tuple[float, ...], u: np.ndarray, a: np.ndarray) -> np.ndarray:
    """da/dt (1/s) of an OpenSim activation law at excitations ``u`` and activations ``a``."""
    e = u - a
    if law == "schutte":  # Schutte1993 / Delp1990: time_scale, activation1, activation2
        ts, a1, a2 = params
        return np.where(e >= 0, e * (a1 * u + a2), e * a2) / ts
    if law == "constant":  # Thelen2003Muscle_Deprecated
        ta, td = params
        return np.where(e >= 0, e / ta, e / td)
    ta, td, b = params  # tanh_blend: DeGrooteFregly2016Muscle, MeyerFregly2016Muscle
    z, f = 0.5 + 1.5 * a, 0.5 * np.tanh(b * e)
    return e * ((f + 0.5) / (ta * z) + (0.5 - f) * z / td)


def _schutte_time_constants(ts: float, a1: float, a2: float) -> tuple[float, float, float, float]:
    """MuJoCo (activation, deactivation) time constants (s) that best follow Schutte's dynamics.

    Schutte1993's activation rises at ``(u - a)(a1 u + a2)/ts`` and falls at ``(u - a) a2/ts``: its
    rise is fast only when the excitation is high. Matching a full step's 0-90 % rise (the former
    mapping) makes MuJoCo rise about 3.6 times too fast at the moderate excitations of movements,
    so the constants are fitted (:func:`_fitted_time_constants`) starting from that step match.
    Returns the two time constants, the activation RMS and that of the step-matched mapping.
    """
    tau_a, tau_d = ts / (a1 + a2), ts / a2
    step = (tau_a * math.log(10) / (2 * math.log(10) - 1.35), tau_d * math.log(10) / (2 * math.log(6.5 / 2)))
    return _fitted_time_constants("schutte", (ts, a1, a2), step)


@functools.lru_cache(maxsize=16)
def _fitted_time_constants(law: str, params: tuple[float, ...],
                           start: tuple[float, float]) -> tuple[float, float, float, float]:
    """MuJoCo (activation, deactivation) time constants (s) that best follow an OpenSim activation
    law (:func:`_activation_rate`).

    MuJoCo's muscle uses ``(u - a)/tau`` with ``tau = tact (0.5 + 1.5 a)`` rising and
    ``tdeact / (0.5 + 1.5 a)`` falling. Both are integrated (OpenSim's law at 0.1 ms, MuJoCo as it
    steps, 2 ms with step-mean controls) under seeded random sine excitations and the time
    constants, starting at ``start``, minimise the RMS difference of the activations. Returns the
    two time constants, that RMS and the RMS of ``start``.
    """
    from scipy.optimize import minimize

    from o2m.activations import generate_activations

    sets = generate_activations(["m"], ACTIVATION_FIT_SETS, seed=0, p_active=1.0, max_freq=ACTIVATION_FIT_MAX_FREQ)
    u = sets.values[:, :, 0]  # (sets, T) at 2 ms
    dt, sub = 0.002, 20
    # OpenSim's law, Euler at dt/sub on the linearly interpolated excitation, sampled every dt
    fine = np.linspace(0.0, 1.0, sub, endpoint=False)
    a = np.zeros_like(u)
    act = np.zeros(u.shape[0])
    for k in range(u.shape[1] - 1):
        a[:, k] = act
        for f in fine:
            act = act + (dt / sub) * _activation_rate(law, params, u[:, k] + f * (u[:, k + 1] - u[:, k]), act)
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

    x0 = np.log(start)
    best = minimize(mujoco_rms, x0, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-7})
    x = best.x if best.fun < mujoco_rms(x0) else x0
    return float(math.exp(x[0])), float(math.exp(x[1])), float(mujoco_rms(x)), float(mujoco_rms(x0))


def _tabulated_inverse(v_of_f, f_lo: float, f_hi: float, u: np.ndarray) -> np.ndarray:
    """fv(u) for a monotone fiber-velocity(force) function: tabulate and interpolate."""
    f = np.linspace(f_lo, f_hi, 4001)
    v = np.array([v_of_f(x) for x in f])
    order = np.argsort(v)
    return np.interp(u, v[order], f[order])


def _thelen_fiber_velocity(af: float, flen: float, threshold: float, damping: float):
    """Thelen's normalized fiber velocity as a function of the force-velocity multiplier, at full
    activation and optimal length (Thelen2003Muscle::calcdlceN; Thelen2003Muscle_Deprecated's
    calcFiberVelocity adds ``damping`` to the denominator): ``(fv - 1) / b``, ``b = 1 + fv/Af``
    shortening, ``(2 + 2/Af)(Flen - fv)/(Flen - 1)`` lengthening, continued linearly below zero force
    and above ``threshold · Flen`` as OpenSim extrapolates."""

    def b_and_slope(fm: float, lengthening: bool) -> tuple[float, float]:
        if not lengthening:
            return 1.0 + fm / af + damping, 1 / af
        return (2 + 2 / af) * (flen - fm) / (flen - 1) + damping, -(2 + 2 / af) / (flen - 1)

    def dlce(fm: float) -> float:
        if 0.0 < fm < flen * threshold:
            return (fm - 1.0) / b_and_slope(fm, fm > 1.0)[0]
        fm0 = 0.0 if fm <= 0.0 else threshold * flen
        b, db = b_and_slope(fm0, fm0 != 0.0)
        slope = 1.0 / b - (fm0 - 1.0) / (b * b) * db
        return (fm0 - 1.0) / b + slope * (fm - fm0)

    return dlce


#: Muscle types whose fiber force has the activation-independent term ``fiber_damping · v / (vmax ·
#: optimal fiber length)`` times the max isometric force (v the fiber velocity, m/s).
FIBER_DAMPED = frozenset({"Millard2012EquilibriumMuscle", "DeGrooteFregly2016Muscle", "MeyerFregly2016Muscle"})


def fiber_damping(m, type_name: str) -> float:
    """The muscle's normalized fiber damping (force / max isometric force per normalized fiber
    velocity; 0 for a type without the term). Millard's default is 0.1: a passive damper that
    resists every fiber motion, even unexcited."""
    return _prop(m, "fiber_damping", 0.0) if type_name in FIBER_DAMPED else 0.0


def _force_velocity(m, type_name: str, u: np.ndarray) -> tuple[np.ndarray, float, list[str]]:
    """OpenSim's force-velocity multiplier at full activation and optimal length, at normalized
    fiber velocities ``u`` (fiber velocity / (vmax * optimal fiber length), negative =
    shortening), and vmax in optimal fiber lengths per second."""
    osim = runtime.opensim()
    notes: list[str] = []
    if type_name == "Thelen2003Muscle":
        af, flen = _prop(m, "Af"), _prop(m, "Flen")
        dlce = _thelen_fiber_velocity(af, flen, _prop(m, "fv_linear_extrap_threshold", 0.95), 0.0)
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
    if type_name == "MeyerFregly2016Muscle":  # its fiber damping is the tendon's (fiber_damping)
        fv = np.array([osim.MeyerFregly2016Muscle.calcForceVelocityMultiplier(float(x)) for x in u])
        return fv, _prop(m, "max_contraction_velocity"), notes
    if type_name == "Delp1990Muscle_Deprecated":
        return _delp_force_velocity(m, u, notes)
    if type_name == "Thelen2003Muscle_Deprecated":
        return _thelen_deprecated_force_velocity(m, u, notes)
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


def _function_prop(obj, name: str):
    """An OpenSim Function held in an object property, by name."""
    osim = runtime.opensim()
    return osim.Function.safeDownCast(obj.getPropertyByName(name).getValueAsObject())


def _delp_force_velocity(m, u: np.ndarray, notes: list[str]) -> tuple[np.ndarray, float, list[str]]:
    """Delp1990Muscle_Deprecated's ``force_velocity_curve``, a function of the fiber velocity in
    optimal fiber lengths per ``time_scale`` (-1 = max shortening): vmax = 1/time_scale."""
    osim = runtime.opensim()
    fn, ts = _function_prop(m, "force_velocity_curve"), _prop(m, "time_scale")
    fv = np.array([fn.calcValue(osim.Vector(1, float(x))) for x in u])
    notes.append(f"Delp1990 force-velocity: max shortening velocity 1/time_scale = {1 / ts:.3g} optimal fiber "
                 f"lengths/s; the muscle's mass ({_prop(m, 'mass', 0.0):.3g}, normalized) is left out")
    return np.maximum(fv, 0.0), 1.0 / ts, notes


def _thelen_deprecated_force_velocity(m, u: np.ndarray, notes: list[str]) -> tuple[np.ndarray, float, list[str]]:
    """Thelen2003Muscle_Deprecated::calcFiberVelocity inverted at full activation and optimal length
    (velocity in ``Vmax`` optimal fiber lengths/s, damping included)."""
    af, flen = _prop(m, "Af"), _prop(m, "Flen")
    fv = _tabulated_inverse(_thelen_fiber_velocity(af, flen, 0.95, _prop(m, "damping")), -0.5, flen * 1.2, u)
    vmax, vmax0 = _prop(m, "Vmax"), _prop(m, "Vmax0")
    notes.append(f"Thelen2003Muscle_Deprecated force-velocity at full activation: max shortening velocity "
                 f"Vmax = {vmax:.3g} optimal fiber lengths/s (OpenSim lowers it towards Vmax0 = {vmax0:.3g} "
                 "as activation falls; MuJoCo's is fixed)")
    return np.maximum(fv, 0.0), vmax, notes
