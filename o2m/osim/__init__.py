"""Reading OpenSim: documents (3.x and 4.x), functions and splines, storage files, and OpenSim itself.

This subpackage is the only place that imports ``opensim`` (:mod:`o2m.osim.runtime`). Its
readers turn an ``.osim`` document into plain dataclasses (:class:`~o2m.osim.skeleton.Skeleton`,
:class:`~o2m.osim.paths.Path`) that the converter writes out; :class:`~o2m.osim.pair.ModelPair`
holds an OpenSim model beside its MuJoCo conversion for the converter's fits and the validators.
OpenSim is Y-up, metres and radians.
"""

from o2m.osim.document import OsimDocument, load_document
from o2m.osim.function_reader import parse_function
from o2m.osim.functions import Function
from o2m.osim.pair import ModelPair
from o2m.osim.simulate import IntegratorSettings, OpenSimRun, read_initial_state, run_isolated, simulate
from o2m.osim.skeleton import Skeleton, read_skeleton
from o2m.osim.storage import Storage, read_sto, write_sto

__all__ = [
    "Function",
    "IntegratorSettings",
    "ModelPair",
    "OpenSimRun",
    "OsimDocument",
    "Skeleton",
    "Storage",
    "load_document",
    "parse_function",
    "read_initial_state",
    "read_skeleton",
    "read_sto",
    "run_isolated",
    "simulate",
    "write_sto",
]
