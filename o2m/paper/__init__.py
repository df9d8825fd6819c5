"""The paper's experiment on MoBL-ARMS (Ikkala & Hämäläinen, 2020): dataset, muscle force fit,
CMA-ES, OpenSim's own muscles in MuJoCo, corrective controls, speed and figures, in the order
:func:`run_paper` runs them."""

from o2m.paper.dataset import Dataset, load_dataset, make_dataset
from o2m.paper.pipeline import (
    FULL,
    QUICK,
    Experiment,
    Settings,
    correction_start,
    fit_muscle_forces,
    fitted_experiment,
    joint_mae,
    load_experiment,
    passive_fibre_stage,
    run_paper,
    schutte_stage,
    write_forces_xml,
)
from o2m.paper.reproduce import PaperRun, format_summary, reproduce

__all__ = [
    "FULL",
    "QUICK",
    "Dataset",
    "Experiment",
    "PaperRun",
    "Settings",
    "correction_start",
    "fit_muscle_forces",
    "fitted_experiment",
    "format_summary",
    "joint_mae",
    "load_dataset",
    "load_experiment",
    "make_dataset",
    "passive_fibre_stage",
    "reproduce",
    "run_paper",
    "schutte_stage",
    "write_forces_xml",
]
