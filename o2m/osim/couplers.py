"""Poses of a model whose only constraints are CoordinateCouplerConstraints, without assembly.

A coupler says ``dependent = scale_factor * function(independents)``. Setting each dependent
from its function, after the coordinates it depends on, satisfies every such constraint exactly;
OpenSim's assembler (``Model::assemble``) reaches the same pose to its tolerance, iteratively
(so much more slowly), and can fail and relax the constraints at poses where the function is
defined.
"""

from __future__ import annotations

from typing import Any

from o2m.osim import runtime

__all__ = ["coupler_chain", "satisfy_constraints", "set_coupled"]


def coupler_chain(model: Any, state: Any, *, partial: bool = False) -> list[tuple[Any, list[Any], Any, float]] | None:
    """The enforced couplers of ``model`` as (dependent Coordinate, independent Coordinates,
    Function, scale factor), each after the couplers that set its independents; None when some
    enforced constraint is not a coupler (unless ``partial``: then the couplers alone, which
    satisfy only their own constraints), a coupler names a coordinate the model lacks, or the
    couplers form a cycle: then only OpenSim's assembler poses the model."""
    osim = runtime.opensim()
    cs = model.getCoordinateSet()
    by_name = {cs.get(i).getName(): cs.get(i) for i in range(cs.getSize())}
    constraints = model.getConstraintSet()
    pending = []
    for i in range(constraints.getSize()):
        con = constraints.get(i)
        if not con.isEnforced(state):
            continue
        cc = osim.CoordinateCouplerConstraint.safeDownCast(con)
        if cc is None:
            if partial:
                continue
            return None
        names = cc.getIndependentCoordinateNames()
        indep = [names.get(j) for j in range(names.getSize())]
        dep = cc.getDependentCoordinateName()
        if dep not in by_name or any(n not in by_name for n in indep):
            return None
        pending.append((dep, indep, cc.getFunction(), _scale_factor(osim, cc)))
    dependents = {p[0] for p in pending}
    done: set[str] = set()
    chain = []
    while pending:
        ready = [p for p in pending if all(n not in dependents or n in done for n in p[1])]
        if not ready:
            return None
        for p in ready:
            chain.append((by_name[p[0]], [by_name[n] for n in p[1]], p[2], p[3]))
            done.add(p[0])
            pending.remove(p)
    return chain


def _scale_factor(osim: Any, coupler: Any) -> float:
    """A coupler's ``scale_factor`` (1 when absent; the bindings have no accessor for it)."""
    if not coupler.hasProperty("scale_factor"):
        return 1.0
    return float(osim.PropertyHelper.getValueDouble(coupler.getPropertyByName("scale_factor")))


def set_coupled(chain: list[tuple[Any, list[Any], Any, float]], state: Any) -> None:
    """Set every dependent coordinate of :func:`coupler_chain`'s ``chain`` in ``state`` from
    the coordinates it depends on (values as in the state; nothing realised)."""
    osim = runtime.opensim()
    for dep, indep, fn, scale in chain:
        x = osim.Vector(len(indep), 0.0)
        for j, c in enumerate(indep):
            x.set(j, c.getValue(state))
        dep.setValue(state, scale * fn.calcValue(x), False)


def satisfy_constraints(model: Any, chain: list[tuple[Any, list[Any], Any, float]] | None, state: Any) -> None:
    """Satisfy ``model``'s constraints in ``state``: from the couplers of ``chain`` where
    :func:`coupler_chain` found them the only ones, else by OpenSim's assembler (which raises
    where it fails)."""
    if chain is None:
        model.assemble(state)
    else:
        set_coupled(chain, state)
