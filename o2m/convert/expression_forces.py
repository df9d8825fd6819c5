"""ExpressionBasedCoordinateForce as a joint spring and damper, when its expression is linear;
SpringGeneralizedForce, always linear, likewise; ExpressionBasedBushingForce as a BushingForce
when each of its six expressions is its own deflection times a constant.

OpenSim applies the generalized force ``f(q, qdot)`` (N m or N) to its coordinate, ``f`` a Lepton
expression of the coordinate's value ``q`` and speed ``qdot``. When ``f = a q + b qdot + c`` on the
coordinate's range (and speeds of a few turns a second), MuJoCo's joint spring and damping give it
exactly: ``stiffness = -a``, ``springref = c / -a``, ``damping = -b``, added to the joint's others
(:func:`o2m.convert.limit_forces.set_joint_passive`). Any other expression (non-linear, a constant
force without stiffness, a coordinate without its own joint) is skipped with the reason.
Linearity is checked by evaluating the expression on a grid (a restricted evaluator: numbers,
``q``, ``qdot``, + - * / ^ and Lepton's functions), not by algebra. A SpringGeneralizedForce is
``-stiffness (q - rest_length) - viscosity qdot``: ``stiffness``, ``springref = rest_length`` and
``damping = viscosity``. An ExpressionBasedBushingForce's ``Mx_expression`` ... ``Fz_expression``
(of ``theta_x`` ... ``delta_z``) that are ``k theta_x`` ... ``k delta_z`` are a BushingForce of
those stiffnesses and its damping (:func:`o2m.convert.bushings.convert_bushing_gains`; OpenSim
gives the two the same forces); any other (coupled, offset or non-linear) is skipped with the reason.
"""

from __future__ import annotations

import ast

import numpy as np
from lxml import etree

from o2m.convert.bushings import convert_bushing_gains
from o2m.convert.force_context import (
    JointSpring,
    _Context,
    _coordinate,
    _number,
    _text,
    _vector,
    note_force_on_hinge,
)
from o2m.convert.limit_forces import set_joint_passive
from o2m.osim.skeleton import Skipped

__all__ = ["EXPRESSION_LINEAR_TOLERANCE", "convert_expression_bushing", "convert_expression_force",
           "convert_spring_generalized_force", "evaluate", "evaluate_expression"]

#: An expression counts as linear when a plane a q + b qdot + c fits it within this fraction of
#: its largest magnitude on the grid.
EXPRESSION_LINEAR_TOLERANCE = 1e-9
#: Speeds over which linearity is checked (rad/s or m/s of the coordinate's unit).
_SPEED = 20.0
_FUNCTIONS = {"sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos,
              "atan": np.arctan, "sinh": np.sinh, "cosh": np.cosh, "tanh": np.tanh, "exp": np.exp,
              "log": np.log, "sqrt": np.sqrt, "abs": np.abs, "min": np.minimum, "max": np.maximum,
              "square": np.square, "cube": lambda x: x ** 3, "step": lambda x: np.where(x >= 0, 1.0, 0.0)}
_BINARY = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply, ast.Div: np.divide, ast.Pow: np.power}


def evaluate_expression(text: str, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
    """Lepton expression ``text`` of ``q`` and ``qdot`` (arrays of one shape) evaluated elementwise.
    Raises ValueError for anything but numbers, q, qdot, + - * / ^ and Lepton's functions."""
    return evaluate(text, {"q": q, "qdot": qdot})


def evaluate(text: str, names: dict[str, np.ndarray]) -> np.ndarray:
    """Lepton expression ``text`` of the variables ``names`` (arrays of one shape), elementwise."""
    tree = ast.parse(text.replace("^", "**"), mode="eval")
    q = next(iter(names.values()))

    def ev(node: ast.AST) -> np.ndarray:
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return np.full_like(q, float(node.value))
        if isinstance(node, ast.Name) and node.id in names:
            return names[node.id]
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = ev(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            return _BINARY[type(node.op)](ev(node.left), ev(node.right))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FUNCTIONS:
            return _FUNCTIONS[node.func.id](*[ev(a) for a in node.args])
        raise ValueError(f"'{ast.unparse(node)}' is not an expression of {', '.join(names)} o2m can evaluate")

    with np.errstate(all="ignore"):
        return np.asarray(ev(tree), dtype=float)


def _own_joint(ctx: _Context, el: etree._Element, coord: str) -> bool:
    """Whether coordinate ``coord`` of force ``el`` has a MuJoCo joint of its own (else the force is
    listed as skipped); an unknown coordinate is an error."""
    b = ctx.builder
    if coord not in b.skel.coordinates:
        raise b.doc.error(el, f"acts on coordinate '{coord}', which no joint defines")
    if coord not in b.coord_joint or b.drivers[coord].base != coord or b.skel.coordinates[coord].locked:
        ctx.out.skipped.append(Skipped(el.tag, el.get("name"), f"coordinate '{coord}' has no joint of its own "
                                       "(locked or coupled): its force is not applied"))
        return False
    return True


def convert_spring_generalized_force(ctx: _Context, el: etree._Element) -> None:
    """SpringGeneralizedForce -> its coordinate's joint spring and damping (see the module)."""
    coord = _coordinate(ctx, el)
    if not _own_joint(ctx, el, coord):
        return
    k, rest, c = (_number(el, prop, 0.0, ctx) for prop in ("stiffness", "rest_length", "viscosity"))
    for prop, v in (("stiffness", k), ("rest_length", rest), ("viscosity", c)):
        if not np.isfinite(v):
            raise ctx.builder.doc.error(el, f"has <{prop}> {v:g}, not a finite number")
    ctx.out.joint_springs.append(JointSpring(el.get("name"), coord, k, rest if k else 0.0, c))
    set_joint_passive(ctx, ctx.spec.joint(coord), coord)
    note_force_on_hinge(ctx, el, coord)



def convert_expression_force(ctx: _Context, el: etree._Element) -> None:
    """ExpressionBasedCoordinateForce -> its coordinate's joint spring and damping (see the module)."""
    b = ctx.builder
    name = el.get("name")
    coord, text = _coordinate(ctx, el), _text(el, "expression")
    if not _own_joint(ctx, el, coord):
        return
    lo, hi = b.fit_range(coord, b.coord_joint[coord][1].kind)
    q, qdot = (g.ravel() for g in np.meshgrid(np.linspace(lo, hi, 21), np.linspace(-_SPEED, _SPEED, 21)))
    try:
        f = evaluate_expression(text or "0", q, qdot)
    except (ValueError, SyntaxError) as exc:
        raise b.doc.error(el, f"has <expression> '{text}': {exc}") from None
    if not np.all(np.isfinite(f)):
        raise b.doc.error(el, f"has <expression> '{text}', not finite on the coordinate's range")
    basis = np.stack([q, qdot, np.ones_like(q)], axis=1)
    (a, damp, c), *_ = np.linalg.lstsq(basis, f, rcond=None)
    off = float(np.max(np.abs(basis @ [a, damp, c] - f)))
    scale = max(float(np.max(np.abs(f))), 1e-300)
    if off > EXPRESSION_LINEAR_TOLERANCE * scale:
        ctx.out.skipped.append(Skipped(el.tag, name, f"'{text}' is not linear in q and qdot ({off:.3g} off a plane "
                                       "over the range): MuJoCo's joint spring and damping cannot give it; its "
                                       "force is not applied"))
        return
    if abs(a) * max(abs(lo), abs(hi), 1.0) <= EXPRESSION_LINEAR_TOLERANCE * scale:
        a = 0.0  # round-off of the fit: no stiffness
    if a == 0.0 and abs(c) > EXPRESSION_LINEAR_TOLERANCE * scale:
        ctx.out.skipped.append(Skipped(el.tag, name, f"'{text}' holds a constant force without stiffness, which a "
                                       "joint spring cannot give; its force is not applied"))
        return
    k = -float(a)
    ref = float(c) / k if k != 0.0 else 0.0
    ctx.out.joint_springs.append(JointSpring(name, coord, k, ref, -float(damp)))
    set_joint_passive(ctx, ctx.spec.joint(coord), coord)
    note_force_on_hinge(ctx, el, coord)


#: The deflections an ExpressionBasedBushingForce's expressions read, in BushingForce's order, with
#: the span (rad, m) over which they are checked for being their own deflection times a constant.
_BUSHING_TERMS = (("Mx_expression", "theta_x", 1.0), ("My_expression", "theta_y", 1.0),
                  ("Mz_expression", "theta_z", 1.0), ("Fx_expression", "delta_x", 0.1),
                  ("Fy_expression", "delta_y", 0.1), ("Fz_expression", "delta_z", 0.1))


def convert_expression_bushing(ctx: _Context, el: etree._Element) -> None:
    """ExpressionBasedBushingForce -> a BushingForce of the same stiffness and damping (see the module)."""
    b = ctx.builder
    if el.find("socket_frame1") is None or el.find("socket_frame2") is None:
        ctx.out.skipped.append(Skipped(el.tag, el.get("name"), "an OpenSim 3.x bushing (no socket_frame1/2) is not "
                                       "converted; its bodies move without its spring and damping"))
        return
    rng = np.random.default_rng(0)
    grid = {var: rng.uniform(-span, span, 200) for _, var, span in _BUSHING_TERMS}
    gains = []
    for prop, var, _ in _BUSHING_TERMS:
        text = _text(el, prop) or "0"
        try:
            f = evaluate(text, grid)
        except (ValueError, SyntaxError) as exc:
            raise b.doc.error(el, f"has <{prop}> '{text}': {exc}") from None
        k = float(np.dot(f, grid[var]) / np.dot(grid[var], grid[var]))
        off = float(np.max(np.abs(f - k * grid[var]), initial=0.0))
        if not np.all(np.isfinite(f)) or off > EXPRESSION_LINEAR_TOLERANCE * max(float(np.max(np.abs(f))), 1e-300):
            ctx.out.skipped.append(Skipped(el.tag, el.get("name"), f"<{prop}> '{text}' is not a constant times "
                                           f"{var} ({off:.3g} off): no BushingForce gives it; its bodies move "
                                           "without its spring and damping"))
            return
        gains.append(k)
    damps = np.concatenate([_vector(el, "rotational_damping", (0.0, 0.0, 0.0), ctx),
                            _vector(el, "translational_damping", (0.0, 0.0, 0.0), ctx)])
    convert_bushing_gains(ctx, el, np.array(gains), damps)

