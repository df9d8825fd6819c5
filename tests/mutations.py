"""Mutation testing of the converter: small valid documents, each changed in one place, and what
becomes of each (shared by ``tests/convert/test_mutations.py`` and ``benchmarks/mutations.py``).

A mutation changes one number of an element's text (to NaN, an infinity, 1e300, 1e-300, a
negative or zero), makes an element's text a word, removes an element, duplicates one beside
itself, or gives a component another component's name; a seeded numpy generator chooses which
and where. Each mutated document is converted (quick, no
fits, unless the change is in a muscle: then with the muscle fit), and the outcome is one of:

* ``converted``: the MJCF loads in MuJoCo and steps :data:`STEPS` steps (no controls) with
  finite positions and no MuJoCo warning of a diverged position, velocity or acceleration;
* ``refused``: an :class:`~o2m.errors.O2MError`, with nothing left in the output folder;
* ``massless, reported``: converted, and the simulation diverges, as the report warns, because a
  body that moves carries no mass (a massless body OpenSim accepts: o2m converts such a
  kinematic model, as WristModel, and says it will not simulate);
* ``crashed`` (any other exception), ``unstable`` (converted, but the simulation diverged) or
  ``left files`` (refused, but files were left behind): each a bug; so is ``unstable, reported``
  (the report warns that the model diverges, for no massless body: a number far out of scale
  but below the 1e10 o2m refuses, which none of the values here is).
"""

from __future__ import annotations

import copy
import shutil
import traceback
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from lxml import etree

from o2m.convert import ConvertOptions, convert
from o2m.errors import O2MError
from o2m.osim.paths import MUSCLE_TYPES

#: What a mutated number becomes (a token of the element's text, or the negative of the one there).
VALUES = ("nan", "inf", "-inf", "1e300", "-1e300", "1e-300", "0", "negative")
#: Mutation kinds and their probabilities.
KINDS = {"number": 0.5, "word": 0.1, "remove": 0.15, "duplicate": 0.15, "rename": 0.1}
#: Steps a converted model must simulate (MuJoCo's default 2 ms step, zero controls).
STEPS = 100
#: The outcomes that are not bugs.
GOOD = ("converted", "refused", "massless, reported")
_BAD_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                 mujoco.mjtWarning.mjWARN_BADQACC)


@dataclass
class Mutation:
    """One mutated document: its ``source`` (a name), the ``kind`` of change, a description
    (``detail``: the element's path and what changed), the document ``text``, and whether the
    change is in a muscle (``muscles``: then the muscle fit runs too)."""

    source: str
    kind: str
    detail: str
    text: str
    muscles: bool


@dataclass
class Outcome:
    """What became of a :class:`Mutation`: ``kind`` (see the module), and a ``message`` (the
    error's, or what went wrong)."""

    mutation: Mutation
    kind: str
    message: str = ""


def _label(el: etree._Element) -> str:
    name = el.get("name")
    return f"{el.tag}[{name}]" if name else str(el.tag)


def _where(el: etree._Element) -> str:
    """The element's path from <Model>, e.g. ``Model/BodySet/objects/Body[block]/mass``."""
    parts = [_label(a) for a in reversed(list(el.iterancestors())) if a.tag != "OpenSimDocument"]
    return "/".join([*parts, _label(el)])


def _numbers(text: str | None) -> list[float] | None:
    try:
        values = [float(t) for t in (text or "").split()]
    except ValueError:
        return None
    return values or None


def _in_muscle(el: etree._Element) -> bool:
    return any(a.tag in MUSCLE_TYPES for a in [el, *el.iterancestors()])


def _elements(root: etree._Element) -> list[etree._Element]:
    """The elements below <Model> (comments left out)."""
    model = root.find("Model")
    return [el for el in model.iter() if isinstance(el.tag, str) and el is not model]


def _change_number(rng: np.random.Generator, els: list[etree._Element]) -> tuple[etree._Element, str]:
    numeric = [el for el in els if len(el) == 0 and _numbers(el.text)]
    el = numeric[rng.integers(len(numeric))]
    tokens = el.text.split()
    k = int(rng.integers(len(tokens)))
    value = VALUES[rng.integers(len(VALUES))]
    new = repr(-float(tokens[k]) or -1.0) if value == "negative" else value
    old = el.text.strip()
    tokens[k] = new
    el.text = " ".join(tokens)
    return el, f"{_where(el)}: '{old}' -> '{el.text}'"


def _mutate(rng: np.random.Generator, root: etree._Element, kind: str) -> tuple[etree._Element, str]:
    """Apply a mutation of ``kind`` to the document ``root``: (the element changed, what changed)."""
    els = _elements(root)
    if kind == "number":
        return _change_number(rng, els)
    if kind == "rename":
        named = [el for el in els if el.get("name")]
        el, other = named[rng.integers(len(named))], named[rng.integers(len(named))]
        old = el.get("name")
        el.set("name", other.get("name"))
        return el, f"{_where(el)}: renamed from '{old}'"
    el = els[rng.integers(len(els))]
    if kind == "word":
        old, el.text = el.text, "o2m"
        return el, f"{_where(el)}: {old!r} -> 'o2m'"
    where = _where(el)
    if kind == "remove":
        parent = el.getparent()
        parent.remove(el)
        return parent, f"{where} removed"
    el.addnext(copy.deepcopy(el))
    return el, f"{where} duplicated"


def mutations(sources: dict[str, str], n: int, seed: int = 0) -> list[Mutation]:
    """``n`` mutated documents of the ``sources`` (name -> document text), taken in turn; the
    kinds drawn by :data:`KINDS` from a numpy generator seeded with ``seed``."""
    rng = np.random.default_rng(seed)
    names = sorted(sources)
    out = []
    for i in range(n):
        name = names[i % len(names)]
        root = etree.fromstring(sources[name].encode())
        kind = str(rng.choice(list(KINDS), p=list(KINDS.values())))
        el, detail = _mutate(rng, root, kind)
        text = '<?xml version="1.0" encoding="UTF-8" ?>\n' + etree.tostring(root, encoding="unicode")
        out.append(Mutation(name, kind, detail, text, _in_muscle(el)))
    return out


#: Analytic shapes given to the two-body model's b2.
_SHAPES = ('<attached_geometry><Sphere name="ball"><socket_frame>..</socket_frame><radius>0.05</radius></Sphere>'
           '<Brick name="box"><socket_frame>..</socket_frame><half_lengths>0.02 0.03 0.04</half_lengths>'
           '<Appearance><color>0.2 0.4 0.6</color><opacity>0.5</opacity></Appearance></Brick></attached_geometry>')


def sources(folder: Path) -> dict[str, str]:
    """The documents mutated: Tug_of_War (from the model registry; its meshes are missing) and the
    two-body model of ``tests/convert/test_bad_input.py`` with its muscle over a wrap cylinder, a
    mesh on b1 (an OBJ written in ``folder``, named by its absolute path) and a sphere and a box on b2."""
    from o2m import models
    from tests.convert.test_bad_input import OBJ, _build_base

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "bone.obj").write_text(OBJ)
    tug = models.fetch("opensim-models/Models/Tug_of_War/Tug_of_War.osim").read_text()
    two = _build_base(folder / "two_body.osim", muscle=True, mesh=str((folder / "bone.obj").resolve()))
    return {"tug": tug, "two-body": two.replace('<Body name="b2">', '<Body name="b2">' + _SHAPES, 1)}


def simulates(xml: Path) -> str:
    """"" when the model steps :data:`STEPS` steps with finite positions and no divergence
    warning; else what went wrong."""
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    for _ in range(STEPS):
        mujoco.mj_step(model, data)
    bad = [w.name for w in _BAD_WARNINGS if data.warning[int(w)].number]
    if bad or not np.all(np.isfinite(data.qpos)):
        return f"diverged at t = {data.time:.3f} s ({', '.join(bad) or 'non-finite qpos'})"
    return ""


def _left_behind(folder: Path, out: Path) -> list[str]:
    files = [str(p) for p in out.rglob("*")] if out.exists() else []
    return files + [str(p) for p in folder.glob(".o2m-*")]


def run(mutation: Mutation, folder: Path) -> Outcome:
    """Convert ``mutation``'s document in ``folder`` (emptied first) and classify the outcome."""
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    path, out = folder / "model.osim", folder / "out"
    path.write_text(mutation.text)
    options = ConvertOptions(quick=True, fit_mechanics=mutation.muscles, fit_wraps=False, workers=1)
    try:
        with np.errstate(all="ignore"):
            conv = convert(path, out, options)
    except O2MError as exc:
        left = _left_behind(folder, out)
        return Outcome(mutation, "left files" if left else "refused", str(exc) + (f" (left {left})" if left else ""))
    except Exception as exc:  # a bug: every failure should be an O2MError
        return Outcome(mutation, "crashed", "".join(traceback.format_exception_only(exc)).strip()
                       + "\n" + "".join(traceback.format_tb(exc.__traceback__)[-3:]))
    why = simulates(conv.xml)
    if not why:
        return Outcome(mutation, "converted")
    warned = any("diverges in MuJoCo" in w for w in conv.report.warnings)
    massless = any("carries no mass" in w for w in conv.report.warnings)
    kind = ("massless, reported" if massless else "unstable, reported") if warned else "unstable"
    return Outcome(mutation, kind, why)


def describe(o: Outcome) -> str:
    """One line (or a few) about an outcome, for failure messages and the benchmark."""
    m = o.mutation
    return f"[{o.kind}] {m.source} {m.kind}{' (muscle fit)' if m.muscles else ''}: {m.detail}\n    {o.message}"
