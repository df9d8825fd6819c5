"""Property test of the converter: every mutated document (``tests/mutations.py``) either converts
into a model that loads in MuJoCo and steps 100 steps without diverging, or is refused with an
O2MError that leaves no file behind; or, where a body that moves carries no mass and OpenSim
accepts the model (a massless leaf body), converts with warnings that it is massless and diverges.

A few dozen mutations of Tug_of_War and of a two-body model with a muscle and a wrap cylinder
(seed 0; numbers made NaN, infinite, 1e300, 1e-300, negative or zero, words for numbers,
elements removed or duplicated, components renamed), each converted quick and without fits
unless the change is in a muscle. ``benchmarks/mutations.py`` runs hundreds and counts the outcomes.
"""

from __future__ import annotations

import collections

import pytest

from tests.helpers import require_models
from tests.mutations import GOOD, KINDS, describe, mutations, run, simulates, sources

#: Mutated documents per run: about 5 s on 2 cores.
N_MUTATIONS = 120


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory):
    require_models()
    folder = tmp_path_factory.mktemp("mutations")
    todo = mutations(sources(folder / "sources"), N_MUTATIONS, seed=0)
    return [run(m, folder / f"m{i:03d}") for i, m in enumerate(todo)]


def test_every_mutation_converts_or_is_refused(outcomes):
    bad = [describe(o) for o in outcomes if o.kind not in GOOD]
    counts = collections.Counter(o.kind for o in outcomes)
    assert not bad, f"{dict(counts)}\n" + "\n".join(bad)


def test_mutations_cover_every_kind_both_models_and_the_muscle_fit(outcomes):
    """The seed gives every kind of mutation, on both models, some with the muscle fit, and both
    outcomes (else the property above would say little)."""
    assert {o.mutation.kind for o in outcomes} == set(KINDS)
    assert {o.mutation.source for o in outcomes} == {"tug", "two-body"}
    assert any(o.mutation.muscles for o in outcomes)
    assert {"converted", "refused"} <= {o.kind for o in outcomes}


def test_refusals_name_the_file(outcomes):
    for o in outcomes:
        if o.kind == "refused":
            assert "model.osim" in o.message, describe(o)


def test_a_diverging_model_is_caught(tmp_path):
    """The check the property relies on: a model that diverges at its first steps is not 'converted'."""
    xml = tmp_path / "wild.xml"
    spring = '<mujoco><worldbody><body><joint type="slide" stiffness="{k}" springref="1"/>' \
             '<geom size="0.1" mass="1"/></body></worldbody></mujoco>'
    xml.write_text(spring.format(k=10))
    assert simulates(xml) == ""  # a soft spring
    xml.write_text(spring.format(k=1e30))
    assert "diverged" in simulates(xml)
