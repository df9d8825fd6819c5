"""Write the workbook's notebooks (``notebooks/*.ipynb``) from the cell lists below, and run them.

The notebooks are thin: every computation is an ``o2m`` call. Editing them here keeps them
reviewable as code. The committed notebooks carry the outputs of a full run:

    python tools/build_notebooks.py                # rewrite the sources; unchanged cells keep outputs
    python tools/build_notebooks.py --execute      # rewrite and run them all (full mode, stored data)
    python tools/build_notebooks.py --execute 04   # only the notebooks whose name starts with 04

Outputs are normalised so that a rerun leaves git clean unless a result changed: no timing
metadata, execution counts 1, 2, ..., PNG images re-encoded with a fixed palette, the repository
and cache folders written as relative paths. ``tests/integration/test_notebooks.py`` checks the
sources are what this script writes, the outputs are clean and small, and the notebooks still
run in quick mode.
"""

from __future__ import annotations

import argparse
import base64
import io
import os
import re
import sys
import time
from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

ROOT = Path(__file__).resolve().parents[1]
HERE = ROOT / "notebooks"

PARAMETERS = '''# Parameters. Quick mode (set O2M_QUICK=1, as CI does) uses small budgets and finishes in a
# minute or two; full mode reproduces the stored results.
import os
from pathlib import Path

QUICK = os.environ.get("O2M_QUICK", "0") == "1"
ROOT = Path.cwd().parent if Path.cwd().name == "notebooks" else Path.cwd()
DATA = ROOT / "data" / "mobl_arms"
OUT = ROOT / "out" / "notebooks"
OUT.mkdir(parents=True, exist_ok=True)
print("quick mode" if QUICK else "full mode", "| data:", DATA)'''


def md(text: str):
    return new_markdown_cell(text.strip())


def code(text: str):
    return new_code_cell(text.strip())


NOTEBOOKS: dict[str, list] = {}

NOTEBOOKS["01_conversion.ipynb"] = [
    md("""
# 1. Converting MoBL-ARMS from OpenSim to MuJoCo

The MoBL-ARMS upper-limb model (Saul et al. 2015) has a fixed torso, a shoulder whose clavicle and
scapula follow the humerus through coupled coordinates, an elbow, a forearm, and 50 muscles. This
notebook converts it with `o2m.convert`, reads the conversion report (what was approximated, with
its measured error), checks the result against OpenSim, and shows the model in 3-D.

Conventions: OpenSim is Y-up, MuJoCo Z-up (o2m rotates +90° about x); lengths in metres, angles in
radians, forces in newtons. A MuJoCo body has the name and frame of its OpenSim body; a MuJoCo
joint named as an OpenSim coordinate has its value.
"""),
    code(PARAMETERS),
    md("""
## Fetch and convert

`fetch_model_with_geometry` copies the model and its meshes into a local cache, checking every
file's sha256. We use the *testing* model without wrap objects (wrist flexion and deviation
locked): it is the model the OpenSim reference simulations use, because OpenSim cannot simulate
the wrapped model in reasonable time.
"""),
    code('''
from o2m import models
from o2m.convert import ConvertOptions, convert

fetched = models.fetch_model_with_geometry("mobl_arms_no_wrap", progress=False)
result = convert(fetched.osim, OUT / "mobl_arms", ConvertOptions(quick=QUICK), geometry_dirs=[fetched.geometry_dir])
print(result.xml)  # the report keeps the conversion time: result.report.seconds'''),
    md("""
## What the converter approximated

MuJoCo has no spline couplings, moving path points, conditional path points or OpenSim muscle
models. The report lists each approximation with its worst error over the coordinate's range.
"""),
    code('''
print(result.report.summary(timing=False)[:4000])'''),
    md("""
## Kinematics against OpenSim

Random poses inside the coordinate ranges, the same independent coordinates set in both models;
errors are the body-origin distance (mm) and the orientation difference (degrees).
"""),
    code('''
from o2m.validate import compare_kinematics

kin = compare_kinematics(fetched.osim, result.xml, n_poses=10 if QUICK else 200, seed=0, progress=False)
print(kin.summary())'''),
    md("""
## Muscle-tendon lengths and moment arms

`compare_muscles` sets the same poses in both models and compares each muscle's length and its
moment arms. The plot shows a moment arm against the elbow angle in both simulators.
"""),
    code('''
from o2m.validate import compare_muscles, plot_moment_arms

mus = compare_muscles(fetched.osim, result.xml, n_poses=10 if QUICK else 200, seed=0)
print(mus.summary()[:3000])'''),
    code('''
import matplotlib.pyplot as plt

fig, axes = plt.subplots(1, 3, figsize=(12, 3))
for ax, muscle in zip(axes, ["BIClong", "TRIlong", "BRA"]):
    plot_moment_arms(fetched.osim, result.xml, muscle, "elbow_flexion", ax=ax, n=21 if QUICK else 101)
plt.tight_layout(); plt.show()'''),
    md("""
## The model in 3-D

`o2m.viz` draws the converted model with meshcat: bones, muscle paths coloured by activation,
markers. The scene is exported to a self-contained HTML file, shown here in a frame (drag to
rotate, scroll to zoom).
"""),
    code('''
import mujoco
from o2m.viz import notebook_iframe, show_pose

model = mujoco.MjModel.from_xml_path(str(result.xml))
html = OUT / "mobl_arms_scene.html"
show_pose(model, model.qpos0, html=html, decimate=0.003).close()  # 0.003 m mesh grid: ~1.3 MB page
print(f"{html.stat().st_size / 1e6:.1f} MB")
notebook_iframe(html)'''),
]

NOTEBOOKS["02_activations.ipynb"] = [
    md("""
# 2. Random muscle-activation sets

The paper drives the model with random excitations: 1 s long, sampled at 500 Hz (every 2 ms,
MuJoCo's time step). Each muscle is active with probability 1/3, as a slow sine

$u(t) = A\\,(1 + \\sin(2\\pi f t + \\varphi))/2$, with $A \\sim U(0,1]$, $f \\sim U(0, 1]$ Hz,
$\\varphi \\sim U(0, 2\\pi)$,

and zero otherwise. Both simulators turn these excitations into muscle activations with their own
first-order activation dynamics. A seed makes the sets reproducible.
"""),
    code(PARAMETERS),
    code('''
from o2m.paper import load_dataset

ds = load_dataset(DATA)
sets = ds.activations
print(f"{len(sets)} sets x {len(sets.times)} samples x {len(sets.muscles)} muscles, seed {sets.seed}")
print(f"fraction of active muscles: {sets.active.mean():.3f} (expected 1/3)")'''),
    md("The stored sets are exactly what the generator gives for the stored seed:"),
    code('''
import numpy as np
from o2m.activations import generate_activations

again = generate_activations(sets.muscles, 3, seed=sets.seed)
print("identical:", np.array_equal(again.values, sets.values[:3]))'''),
    md("## One set, muscle by muscle"),
    code('''
import matplotlib.pyplot as plt

i = 0
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4))
im = ax1.imshow(sets.values[i].T, aspect="auto", extent=[0, 1, len(sets.muscles), 0], vmin=0, vmax=1)
ax1.set_yticks(np.arange(len(sets.muscles)) + 0.5, sets.muscles, fontsize=5)
ax1.set_xlabel("time (s)"); ax1.set_title(f"set {i}: excitation per muscle")
fig.colorbar(im, ax=ax1)
for m in np.flatnonzero(sets.active[i]):
    ax2.plot(sets.times, sets.values[i, :, m], label=sets.muscles[m])
ax2.set_xlabel("time (s)"); ax2.set_ylabel("excitation"); ax2.set_title("the active muscles")
ax2.legend(fontsize=6, ncol=2)
plt.show()'''),
    md("## Over all sets: how many muscles are active, and at what frequency"),
    code('''
fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3))
a.hist(sets.active.sum(axis=1), bins=20); a.set_xlabel("active muscles per set")
b.hist(sets.frequency[sets.active], bins=20); b.set_xlabel("sine frequency (Hz)")
plt.show()'''),
]

NOTEBOOKS["03_forward_simulation.ipynb"] = [
    md("""
# 3. Forward simulation in OpenSim and MuJoCo

The same excitations drive OpenSim 4.6 (the reference) and the converted MuJoCo model (2 ms
steps), from the same initial state (MoBL-ARMS' `initial_states.sto`). OpenSim's trajectories are
stored in `data/` because they are slow to compute; here we rerun one of them to see the cost,
simulate the same set in MuJoCo, and compare.
"""),
    code(PARAMETERS),
    code('''
from o2m.paper import load_experiment

exp = load_experiment(DATA, OUT / "paper")
ds = exp.dataset
print(f"{int(ds.ok.sum())} of {len(ds.ok)} OpenSim runs succeeded")
for i, status, reason in ds.failures():
    print(f"  set {i}: {status}: {reason}")
print("free DoFs:", exp.dofs)'''),
    md("""
## One set in OpenSim, live

OpenSim integrates with an error-controlled Runge-Kutta-Merson method (accuracy 1e-5, as the
paper's `setup_fd.xml`). In quick mode we simulate only the first 0.1 s.
"""),
    code('''
import numpy as np
from o2m import models
from o2m.osim import IntegratorSettings, read_initial_state, simulate

i = ds.test[0]
n = 51 if QUICK else len(ds.times)
run = simulate(models.fetch_model(ds.meta["model"], progress=False), ds.times[:n], ds.activations.values[i, :n],
               list(ds.activations.muscles), initial_state=read_initial_state(models.fetch(ds.meta["initial_state"])),
               settings=IntegratorSettings(**ds.meta["integrator"]))
print(run.status, f"{run.times[-1]:.3f} s simulated")  # run.integration_time: OpenSim's wall time
cols = [run.coordinate_names.index(d) for d in exp.dofs]
print("max difference from the stored run (rad):", np.abs(run.coordinates[:, cols] - exp.reference[i, :n]).max())'''),
    md("## The same set in MuJoCo"),
    code('''
from o2m.mj import rollout

# MuJoCo's time for this: %time in a cell, or the speed benchmark's stored numbers below
tr = rollout(exp.model, exp.init[[i]], exp.controls[[i]], joint_names=exp.dofs)
print(f"1 s simulated; diverged: {bool(tr.diverged[0])}")'''),
    code('''
import matplotlib.pyplot as plt
from o2m.paper.figures import overlay

overlay(ds.times, exp.dofs, exp.reference[i], {"MuJoCo (converted)": tr.coordinates[0]}, f"test set {i}")
plt.show()
mae = np.abs(tr.coordinates[0] - exp.reference[i]).mean(0)
print("mean absolute error per DoF (rad):", dict(zip(exp.dofs, mae.round(3))))'''),
    md("""
## Speed

`python -m o2m speed` times one 1-s simulation in each simulator on this machine (OpenSim:
integration only, model loading excluded; MuJoCo: a plain step loop on one thread). The full
result is stored in `data/mobl_arms/speed.json`.
"""),
    code('''
import json
speed = json.loads((DATA / "speed.json").read_text()) if (DATA / "speed.json").exists() else None
if speed:
    print(f"OpenSim {speed['opensim_median_s']:.2f} s, MuJoCo {speed['mujoco_median_s']:.4f} s: "
          f"{speed['ratio']:.0f}x; batched rollouts: {speed['rollout_per_s']:.0f} simulations/s "
          f"on {speed['rollout_threads']} threads")'''),
    md("""
## Both motions side by side in 3-D

One side is OpenSim's motion, posed by OpenSim's own kinematics from its stored coordinates (in
beige, with OpenSim's muscle paths); the other is MuJoCo's. Muscle paths are coloured by MuJoCo's
activation (blue 0, red 1). Press play in the meshcat controls (Animations).
"""),
    code('''
from o2m.viz import notebook_iframe, side_by_side

step = 50 if QUICK else 10  # a frame every 0.1 s (quick) or 20 ms, played in real time
html = OUT / "side_by_side.html"
side_by_side(exp.model, models.fetch_model(ds.meta["model"], progress=False), ds.coordinate_names,
             ds.coordinates[i, ::step], tr.qpos[0, ::step], fps=500 / step, activations=tr.act[0, ::step],
             html=html, decimate=0.003, tendon_stride=2).close()
print(f"{html.stat().st_size / 1e6:.1f} MB")
notebook_iframe(html)'''),
]

NOTEBOOKS["04_parameter_fitting.ipynb"] = [
    md("""
# 4. Fitting the model's dynamics to OpenSim

Geometry converts exactly or nearly so; dynamics do not. MuJoCo's muscle has a rigid tendon and
fixed curve shapes, while MoBL-ARMS' Schutte muscles have an elastic tendon and damped fibres.
We fit the converted model in three stages, both on the training sets only:

1. **Muscle forces** (o2m's addition to the paper). The dataset records OpenSim's tendon force of
   every muscle every 2 ms. At each of those states, MuJoCo's muscle should pull as hard. We fit,
   muscle by muscle, MuJoCo's force-length and force-velocity parameters and strength, and move
   the passive force into a polynomial spring on the muscle's tendon (plus tendon damping), by
   least squares. This is cheap (no simulation) and removes most of the error.
2. **Passive fibres** (o2m's addition). A Schutte muscle that is never excited in a set keeps its
   fibre as long as it has ever been there: after a stretch its tendon goes slack, where MuJoCo's
   memoryless passive force keeps pulling. Each set's never-excited elbow and forearm muscles pull
   as OpenSim's fibre does, inside MuJoCo (the `o2m.fibre` plugin, compiled at first use).
3. **The paper's 160 parameters** with CMA-ES: per free DoF its damping and the softness of its
   limit, per muscle tendon its damping and spring, per muscle a strength scale, so that the
   joint trajectories match OpenSim's.

Beside it we run **the paper's pipeline** as the paper did: the same CMA-ES fit straight on the
converted model (no muscle force fit), keeping the best candidate on the training sets. o2m's
additions, all absent from that column: the muscle force fit, the passive fibres, early stopping on held-out
validation sets, and (notebook 5) the corrections' force-matching start and their search by
Levenberg-Marquardt instead of CMA-ES. Shared by both columns
and different from the paper: each parameter is searched within one decade of its converted value
with a penalty of 1e-3 rad² per decade² of change (the paper: log-space search with a price of
1e-3 per unit of parameter value), and a smaller budget (12 candidates a generation; the paper
ran up to 500 generations of 16).
"""),
    code(PARAMETERS),
    code("""
import numpy as np
from o2m.paper import FULL, QUICK as QUICK_SETTINGS, fit_muscle_forces, load_experiment

exp = load_experiment(DATA, OUT / "paper")
print(len(exp.dataset.train), "training sets,", len(exp.dataset.test), "test sets;", len(exp.muscles), "muscles;",
      "free DoFs:", exp.dofs)"""),
    md("""
## Stage 1: muscle forces

In quick mode we fit on four training sets with a small budget; in full mode we load the stored
fit (`data/mobl_arms/results/muscle_forces.json`, made by `python -m o2m paper`). Errors are RMS
over states, in % of each muscle's max isometric force; "held out" are training sets the fit did
not see. A muscle keeps its converted force unless the fit is better on those.
"""),
    code("""
if QUICK:
    forces = fit_muscle_forces(exp, exp.dataset.train[:4], OUT / "muscle_forces.json", settings=QUICK_SETTINGS,
                               refit=True, progress=False)
else:
    forces = fit_muscle_forces(exp, exp.dataset.train, DATA / "results" / "muscle_forces.json", settings=FULL)
s = forces.summary()
print(f"RMS force error on held-out states: {s['rms_held_out_start']:.2f} -> {s['rms_held_out']:.2f} % of max force"
      f" ({s['kept']} of {s['muscles']} muscles changed)")
worst = sorted(forces.muscles.values(), key=lambda f: -f.rms_held_out_start)[:5]
for f in worst:
    print(f"  {f.name:8s} {f.rms_held_out_start:5.2f} -> {f.rms_held_out:5.2f} %")"""),
    md("One test set, the muscle the fit helped most: OpenSim's tendon force against MuJoCo's at the same states."),
    code("""
import matplotlib.pyplot as plt
from o2m.paper.force_fit import pulling_force, sample_states

ds = exp.dataset
i = ds.test[0]
fitted_forces = forces.apply(exp.model)
states = sample_states(exp.model, ds.coordinates[[i]], ds.speeds[[i]], ds.opensim_activations[[i]],
                       ds.tendon_forces[[i]], ds.coordinate_names, ds.muscle_names, stride=1)
name = max(forces.muscles.values(), key=lambda f: f.rms_held_out_start - f.rms_held_out).name
j = ds.muscle_names.index(name)
t = ds.times[: len(states.force)]
plt.figure(figsize=(9, 3))
plt.plot(t, states.force[:, j], "k", lw=2, label="OpenSim tendon force")
for label, m in (("converted", exp.model), ("muscle forces fitted", fitted_forces)):
    f = pulling_force(m, name, states.length[:, j], states.velocity[:, j], states.activation[:, j])
    plt.plot(t, f, label=label)
plt.xlabel("time (s)"); plt.ylabel("force (N)"); plt.title(f"{name}, test set {i}"); plt.legend(); plt.show()"""),
    md("""
## Stages 2 and 3: passive fibres, then the paper's CMA-ES fit

The objective is the squared joint error (rad²) averaged over time and summed over DoFs and
training sets, plus a small penalty on moving parameters far (in log10 units) from their start.
"""),
    code("""
from o2m.paper import passive_fibre_stage, write_forces_xml
from o2m.paper.fitting import BOUNDS, PENALTY, TrajectoryObjective, fit_cma, load_fit, parameter_space

# stage 2: the force-fitted model with each set's never-excited elbow and forearm muscles as passive
# fibres; fibre_exp lays the sets out for it (their initial states switch the fibres on or off)
fibre_exp = passive_fibre_stage(exp, write_forces_xml(exp, forces))
print(fibre_exp.model.nplugin, "muscles can pull as passive fibres")
space = parameter_space(fibre_exp.model, exp.dofs, exp.muscles)
print(len(space), "parameters; penalty weight", PENALTY)
for kind, (lo, hi) in BOUNDS.items():
    count = sum(n.startswith(kind + ":") for n in space.names)
    if count:
        print(f"{kind:18s} {count:3d} parameters, bounds {lo:g} .. {hi:g}")
if QUICK:
    train = exp.dataset.train[:4]
    objective = TrajectoryObjective(fibre_exp.model, space, fibre_exp.init[train], exp.controls[train],
                                    exp.reference[train], exp.dofs)
    fit = fit_cma(objective, seed=0, generations=3, popsize=6, progress=False)
else:
    fit = load_fit(DATA / "results" / "parameters.json")
print(f"cost {fit.cost0:.4g} -> {fit.cost:.4g}; {fit.evaluations} candidates in {fit.wall_time:.0f} s")"""),
    code("""
plt.plot(fit.history); plt.xlabel("generation"); plt.ylabel("best training cost (rad²)"); plt.show()
if np.array_equal(fit.x, fit.x0):
    print(f"the fit kept its start: no candidate better on the training sets (best seen "
          f"{fit.settings.get('best_training_cost', fit.cost):.4g}) was also better on the validation sets")
else:
    values, start = space.values(fit.x), space.values(space.x0)
    moved = sorted(space.names, key=lambda n: -abs(fit.x[space.names.index(n)] - space.x0[space.names.index(n)]))
    print("the ten parameters the fit moved most (log10 units):")
    for n in moved[:10]:
        print(f"  {n:32s} {start[n]:10.4g} -> {values[n]:10.4g}")"""),
    md("""
## The paper's pipeline: CMA-ES on the converted model

The same fit, started from the converted model and not early-stopped: what the paper's method
gives on its own. Its validation cost is only reported.
"""),
    code("""
paper_space = parameter_space(exp.model, exp.dofs, exp.muscles)
if QUICK:
    paper_objective = TrajectoryObjective(exp.model, paper_space, exp.init[train], exp.controls[train],
                                          exp.reference[train], exp.dofs)
    paper_fit = fit_cma(paper_objective, seed=0, generations=3, popsize=6, progress=False, early_stopping=False)
else:
    paper_fit = load_fit(DATA / "results" / "parameters_paper.json")
print(f"training cost {paper_fit.cost0:.4g} -> {paper_fit.cost:.4g}; validation cost "
      f"{paper_fit.validation_cost0:.4g} -> {paper_fit.validation_cost:.4g}; {paper_fit.evaluations} candidates")"""),
    md("""
## OpenSim's own muscles inside MuJoCo: nothing to fit

Every stage above fits MuJoCo's muscle to behave like OpenSim's. o2m can instead run OpenSim's
muscle itself inside MuJoCo: the `o2m.schutte` actuator plugin (compiled at first use) is
Schutte's muscle with its elastic tendon and its fibre, whose activation and fibre length are
the plugin's state, each muscle with its own parameters and curves read from the `.osim`. Each
set starts where OpenSim started (its initial activations and fibre lengths). Nothing is fitted:
the converted model's skeleton and paths, OpenSim's muscles.
"""),
    code("""
from o2m.paper import schutte_stage

schutte_exp = schutte_stage(exp)  # the converted model with every muscle an o2m.schutte actuator
print(schutte_exp.model.nu, "actuators,", schutte_exp.model.npluginstate, "plugin states;", schutte_exp.xml.name)"""),
    md("## Test error per joint, stage by stage"),
    code("""
from o2m.paper import joint_mae

test = exp.dataset.test[:3] if QUICK else exp.dataset.test
# each stage's model with the sets laid out for it
stages = {"converted": (exp, exp.model), "paper: CMA-ES": (exp, paper_space.apply(exp.model, paper_fit.x)),
          "o2m: forces": (exp, fitted_forces), "o2m: + fibres": (fibre_exp, fibre_exp.model),
          "o2m: + CMA-ES": (fibre_exp, space.apply(fibre_exp.model, fit.x)),
          "o2m: OpenSim": (schutte_exp, schutte_exp.model)}
errors = {k: np.nanmean(joint_mae(e, m, test)[0], axis=0) for k, (e, m) in stages.items()}
print(f"{'DoF':15s}" + "".join(f"{k:>15s}" for k in errors) + "   (mean absolute error, rad)")
for j, d in enumerate(exp.dofs):
    print(f"{d:15s}" + "".join(f"{e[j]:15.4f}" for e in errors.values()))
print(f"{'mean':15s}" + "".join(f"{e.mean():15.4f}" for e in errors.values()))"""),
]

NOTEBOOKS["05_corrective_controls.ipynb"] = [
    md("""
# 5. Corrective controls

Even a fitted model drifts from OpenSim. The paper asks how small a change of the excitations
makes MuJoCo follow OpenSim: per muscle, a correction shaped as a cubic spline with knots every
0.1 s (10 Hz) is added to the reference excitation (and clipped to [0, 1]). The corrections
minimise the joint error plus an L2 penalty on their size. `o2m.paper.corrections` optimises the
spline coefficients block by block in time, in several passes over the blocks (each pass revisits
a block after the later ones have moved), and keeps a block only if it lowers the whole
trajectory's cost. The paper searched each block with CMA-ES; o2m's pipeline uses
Levenberg-Marquardt (the block's cost is a sum of squares, and its short window is nearly linear in
the corrections), which leaves a smaller error with smaller corrections. It starts from the
better of no correction and the correction that, along OpenSim's own trajectory, would make every
MuJoCo muscle pull with the tendon force OpenSim recorded (o2m's addition: the dataset keeps
those forces).
"""),
    code(PARAMETERS),
    code('''
import numpy as np
from o2m.paper.corrections import PENALTY, fit_corrections
from o2m.paper.fitting import load_fit
from o2m.paper.force_fit import ForceFit
from o2m import paper
from o2m.paper import correction_start, fitted_experiment, load_experiment

budget = paper.QUICK if QUICK else paper.FULL  # the main command's budgets
exp = load_experiment(DATA, OUT / "paper")
results = DATA / "results"
if (results / "parameters.json").exists() and (results / "muscle_forces.json").exists():
    # o2m's fitted model, with each set's never-excited elbow and forearm muscles as OpenSim's passive fibres
    exp = fitted_experiment(exp, ForceFit.load(results / "muscle_forces.json"), load_fit(results / "parameters.json"))
    model = exp.model
else:  # no stored fit (a fresh dataset): correct the converted model
    model = exp.model
i = exp.dataset.test[0]
start = correction_start(exp, model, i)  # the correction that would match OpenSim's recorded muscle forces
res = fit_corrections(model, exp.init[i], exp.dataset.activations.values[i], exp.muscles, exp.reference[i], exp.dofs,
                      method=budget.correction_method, iterations=budget.correction_iterations,
                      generations=budget.correction_generations, sweeps=budget.correction_sweeps, seed=0,
                      start=start)
print(f"penalty weight {PENALTY}; cost {res.cost0:.4f} -> {res.cost:.4f}; {res.evaluations} simulated windows")
print("mean absolute joint error (rad):", {d: round(float(e), 4) for d, e in zip(exp.dofs, res.joint_mae0)}, "->",
      {d: round(float(e), 4) for d, e in zip(exp.dofs, res.joint_mae)})
print(f"mean absolute correction: {np.abs(res.correction).mean():.4f}")'''),
    code('''
import matplotlib.pyplot as plt
from o2m.paper.figures import overlay

t = exp.dataset.times
top = np.argsort(-np.abs(res.correction).mean(0))[:6]
fig, ax = plt.subplots(figsize=(10, 3))
for m in top:
    line, = ax.plot(t, exp.dataset.activations.values[i, :, m], "--")
    ax.plot(t, res.excitations[:, m], color=line.get_color(), label=exp.muscles[m])
ax.set_xlabel("time (s)"); ax.set_ylabel("excitation"); ax.set_title("reference (dashed) and corrected")
ax.legend(fontsize=7); plt.show()
from o2m.mj import rollout
base = rollout(model, exp.init[[i]], exp.controls[[i]], joint_names=exp.dofs).coordinates[0]
overlay(t, exp.dofs, exp.reference[i], {"fitted": base, "fitted + corrections": res.coordinates}, f"test set {i}")
plt.show()'''),
    md("""
## The same on OpenSim's own muscles

With each muscle OpenSim's own inside MuJoCo (the `o2m.schutte` plugin, notebook 4's last stage)
the model starts much nearer OpenSim, so the corrections have less to do. They start from no
correction: the force-matching start inverts MuJoCo's muscle, which this model does not have.
"""),
    code('''
from o2m.paper import schutte_stage

own = schutte_stage(load_experiment(DATA, OUT / "paper"))
res_own = fit_corrections(own.model, own.init[i], own.dataset.activations.values[i], own.muscles, own.reference[i],
                          own.dofs, method=budget.correction_method, iterations=budget.correction_iterations,
                          generations=budget.correction_generations, sweeps=budget.correction_sweeps, seed=0)
print("mean absolute joint error (rad):", {d: round(float(e), 4) for d, e in zip(own.dofs, res_own.joint_mae0)}, "->",
      {d: round(float(e), 4) for d, e in zip(own.dofs, res_own.joint_mae)})
print(f"mean absolute correction: {np.abs(res_own.correction).mean():.4f} (MuJoCo's fitted muscles: "
      f"{np.abs(res.correction).mean():.4f})")'''),
]

NOTEBOOKS["06_figures.ipynb"] = [
    md("""
# 6. The paper's figures

Every figure is redrawn from stored results (`data/mobl_arms/results/`, `data/mobl_arms/speed.json`)
by `o2m.paper.figures.make_figures`; nothing is simulated here. `python -m o2m paper` recomputes the
results (`--quick` for a small version in minutes).
"""),
    code(PARAMETERS),
    md("""
The stored results come from `python -m o2m paper` (full mode). Where they are missing (a fresh
dataset, say), quick mode computes a small version first, into `out/`.
"""),
    code('''
import json
from o2m.paper import QUICK as QUICK_SETTINGS, run_paper

results = DATA / "results"
speed_file = DATA / "speed.json"
if not (results / "results.npz").exists():
    if not QUICK:
        raise FileNotFoundError(f"no stored results in {results}: run `python -m o2m paper` first")
    results = OUT / "quick-results"
    run_paper(DATA, settings=QUICK_SETTINGS, model_dir=OUT / "paper", results_dir=results, refit=True, progress=False)
summary = json.loads((results / "summary.json").read_text())
print(json.dumps(summary["mean_error_rad"], indent=1))
print("mean absolute correction:", round(summary["mean_abs_correction"], 4))'''),
    code('''
from IPython.display import Image, display
from o2m.paper.figures import make_figures

target = OUT / "figures" if QUICK else ROOT / "figures"
written = make_figures(results, target, speed_file=speed_file)
for p in written:
    if p.suffix == ".png":
        display(Image(filename=str(p)))'''),
]


KERNELSPEC = {"name": "python3", "display_name": "Python 3", "language": "python"}
INLINE_BACKEND = "module://matplotlib_inline.backend_inline"
"""Matplotlib backend of the executing kernel: a caller's ``MPLBACKEND=Agg`` would leave no figures."""
KERNEL_WARNINGS = "ignore:IProgress not found:Warning"
"""Python warning filter of the executing kernel: tqdm's notice that ipywidgets is missing (it then
draws text bars) is about the machine, not the notebook."""
MAX_IMAGE_WIDTH = 1400
"""Widest stored image (pixels); wider ones (the paper's 150-dpi figures) are scaled down."""


def _fresh_notebook(name: str, cells: list) -> nbformat.NotebookNode:
    """The notebook ``name`` from its cell list, without outputs, every cell with a stable id."""
    cells = [nbformat.from_dict(dict(cell)) for cell in cells]  # copies: NOTEBOOKS stays untouched
    for k, cell in enumerate(cells):
        cell.id = f"{Path(name).stem[:2]}-{k:02d}"  # stable ids: a rebuild changes only what changed
    return new_notebook(cells=cells, metadata={"kernelspec": dict(KERNELSPEC)})


def _keep_outputs(nb: nbformat.NotebookNode, previous: nbformat.NotebookNode) -> None:
    """Copy into ``nb`` the outputs of ``previous``'s code cells whose id and source are unchanged."""
    old = {c.id: c for c in previous.cells if c.cell_type == "code"}
    for cell in nb.cells:
        match = old.get(cell.id)
        if cell.cell_type == "code" and match is not None and match.source == cell.source:
            cell.outputs, cell.execution_count = match.outputs, match.execution_count


def build(folder: Path = HERE) -> list[Path]:
    """Write every notebook into ``folder``; returns the files written.

    A code cell whose source is unchanged keeps the outputs of the notebook already in ``folder``
    (a changed cell loses them, and the execution counts then have a gap until ``--execute``).
    """
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, cells in NOTEBOOKS.items():
        nb, target = _fresh_notebook(name, cells), folder / name
        if target.exists():
            _keep_outputs(nb, nbformat.read(target, as_version=4))
        nbformat.write(nb, target)
        written.append(target)
    return written


def path_replacements(root: Path = ROOT, cache: str | None = None) -> dict[str, str]:
    """Machine paths to hide in outputs -> what to write instead, longest first.

    ``root`` (the repository) becomes ``.``, ``cache`` (o2m's model cache, if given) ``$O2M_CACHE``,
    Python's installation ``$PYTHON`` and the home folder ``~``; both the given and the resolved
    spelling of each are replaced.
    """
    pairs = {}
    for path, label in ((root, "."), (cache, "$O2M_CACHE"), (sys.prefix, "$PYTHON"), (sys.base_prefix, "$PYTHON"),
                        (Path.home(), "~")):
        if path:
            for spelling in {str(Path(path)), str(Path(path).resolve())}:
                pairs.setdefault(spelling, label)
    return dict(sorted(pairs.items(), key=lambda kv: -len(kv[0])))


def _small_png(b64: str) -> str:
    """A base64 PNG re-encoded on white with a 256-colour palette (a third of matplotlib's size),
    at most MAX_IMAGE_WIDTH pixels wide, without metadata; deterministic for a given image."""
    from PIL import Image

    image = Image.open(io.BytesIO(base64.b64decode(b64)))
    if image.mode == "P" and image.width <= MAX_IMAGE_WIDTH:
        return b64  # already normalised: a second pass changes nothing
    image = image.convert("RGBA")
    if image.width > MAX_IMAGE_WIDTH:
        height = round(image.height * MAX_IMAGE_WIDTH / image.width)
        image = image.resize((MAX_IMAGE_WIDTH, height), Image.Resampling.LANCZOS)
    white = Image.new("RGBA", image.size, (255, 255, 255, 255))
    rgb = Image.alpha_composite(white, image).convert("RGB")
    paletted = rgb.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    buffer = io.BytesIO()
    paletted.save(buffer, format="PNG", optimize=True)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


OBJECT_ADDRESS = re.compile(r" at 0x[0-9a-f]+>")


def _replace_paths(text: str | list, replacements: dict[str, str]) -> str:
    """``text`` with machine paths replaced and object addresses (``<... at 0x7f...>``, new in
    every kernel) dropped."""
    text = "".join(text) if isinstance(text, list) else text
    for path, label in replacements.items():
        text = text.replace(path, label)
    return OBJECT_ADDRESS.sub(">", text)


def normalise(nb: nbformat.NotebookNode, replacements: dict[str, str]) -> None:
    """Make an executed notebook reproducible in place: no timing or kernel-version metadata,
    execution counts 1, 2, ... in cell order, small PNGs, machine paths replaced."""
    nb.metadata = nbformat.from_dict({"kernelspec": dict(KERNELSPEC)})
    count = 0
    for cell in nb.cells:
        cell.metadata.pop("execution", None)
        if cell.cell_type != "code":
            continue
        count += 1
        cell.execution_count = count
        for output in cell.outputs:
            if output.output_type == "execute_result":
                output.execution_count = count
            if "text" in output:
                output.text = _replace_paths(output.text, replacements)
            for mime, value in output.get("data", {}).items():
                if mime == "image/png":
                    output.data[mime] = _small_png(value)
                elif mime.startswith("text/"):
                    output.data[mime] = _replace_paths(value, replacements)


def execute(path: Path, *, quick: bool, timeout: float = 7200.0) -> float:
    """Run the notebook at ``path`` top to bottom on a fresh kernel in its folder and write it back
    normalised. ``quick`` sets ``O2M_QUICK`` for the kernel. Returns the wall time (s).
    Raises ``nbclient.exceptions.CellExecutionError`` (the notebook file is then left as it was)."""
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    env = dict(os.environ, O2M_QUICK="1" if quick else "0", MPLBACKEND=INLINE_BACKEND, PYTHONWARNINGS=KERNEL_WARNINGS)
    client = NotebookClient(nb, timeout=timeout, kernel_name=KERNELSPEC["name"],
                            resources={"metadata": {"path": str(path.parent)}})
    start = time.perf_counter()
    client.execute(env=env)
    seconds = time.perf_counter() - start
    normalise(nb, path_replacements(ROOT, os.environ.get("O2M_CACHE")))
    nbformat.write(nb, path)
    return seconds


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description="Write (and with --execute, run) the notebooks in notebooks/.")
    ap.add_argument("--execute", nargs="*", metavar="PREFIX",
                    help="run the notebooks (all, or those whose name starts with a PREFIX) and store outputs")
    ap.add_argument("--quick", action="store_true", help="run in quick mode (to try; commit full-mode outputs)")
    ap.add_argument("--timeout", type=float, default=7200.0, help="seconds allowed per cell")
    args = ap.parse_args(argv)
    from nbclient.exceptions import CellExecutionError

    written = build()
    for path in written:
        print("wrote", path.relative_to(ROOT))
    if args.execute is None:
        return
    chosen = [p for p in written if not args.execute or any(p.name.startswith(x) for x in args.execute)]
    total = 0.0
    for path in chosen:
        try:
            seconds = execute(path, quick=args.quick, timeout=args.timeout)
        except CellExecutionError as exc:
            sys.exit(f"{path.name}: a cell failed; the notebook was not rewritten.\n{exc}")
        total += seconds
        size = path.stat().st_size / 1e3
        print(f"executed {path.name} ({'quick' if args.quick else 'full'} mode) in {seconds:.0f} s, {size:.0f} kB")
    print(f"{len(chosen)} notebooks in {total:.0f} s")


if __name__ == "__main__":
    main()
