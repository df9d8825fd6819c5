"""o2m: convert OpenSim models to MuJoCo and measure their fidelity against OpenSim 4.6."""

__version__ = "0.1.0"
