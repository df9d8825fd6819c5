"""One Levenberg-Marquardt step, shared by the corrections and the window fits.

Both differentiate a batch of simulations by forward differences and then try several dampings
in one more batch (simulations are cheap in batches, serial iterations are not), so the step
here returns every damped candidate at once rather than adapting one damping.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["damped_steps"]


def damped_steps(jac: np.ndarray, residuals: np.ndarray, x: np.ndarray, dampings: Sequence[float],
                 lower: float | np.ndarray, upper: float | np.ndarray) -> np.ndarray:
    """Gauss-Newton steps from ``x`` (n,) damped by Marquardt's scaling, clipped to the bounds.

    Args:
        jac: Jacobian of ``residuals`` at ``x``, shape (r, n).
        residuals: shape (r,); the cost is their sum of squares.
        dampings: each ``λ`` solves ``(JᵀJ + λ diag(JᵀJ)) δ = -Jᵀr``.
        lower, upper: bounds of the candidates (scalars or shape (n,)).

    Returns:
        The candidates ``clip(x + δ)``, shape (len(dampings), n).
    """
    jtj, grad = jac.T @ jac, jac.T @ residuals
    scale = np.diag(np.maximum(np.diag(jtj), 1e-12))
    return np.array([np.clip(x + np.linalg.solve(jtj + lam * scale, -grad), lower, upper) for lam in dampings])
