"""The source's per-view losses and view schedules.

Written with arithmetic and a ``mean`` function only, so the same code runs on Dr.Jit
tensors (for gradients) and on numpy arrays (tests, reports).  ``view_loss_and_grad``
gives a loss and its gradient in numpy, for refinements that sum in numpy so that a
seed gives the same bits every time.
"""

from __future__ import annotations

import numpy as np

LOSSES = ("si_mse", "l1_joint", "l1_weighted")
SCHEDULES = ("cyclic", "joint")


def si_mse(render, target, mean):
    """Scale-independent MSE: both images divided by their mean, then MSE (source 4.1)."""
    return mean(((render / mean(render)) - (target / mean(target))) ** 2)


def l1(render, target, mean):
    """Absolute error summed over pixels, as mean x count (the source's L_joint term)."""
    return mean(abs(render - target))


def view_loss(name: str, render, target, mean, weight: float = 1.0):
    """One view's contribution to the loss named ``name`` (see LOSSES)."""
    if name == "si_mse":
        return si_mse(render, target, mean)
    if name == "l1_joint":
        return l1(render, target, mean)
    if name == "l1_weighted":
        return weight * l1(render, target, mean)
    raise ValueError(f"unknown loss {name!r}")


def view_loss_and_grad(name: str, render: np.ndarray, target: np.ndarray,
                       weight: float = 1.0) -> tuple[float, np.ndarray]:
    """``view_loss`` and its gradient with respect to ``render``: (float, array shaped
    like ``render``), float64 numpy."""
    render = np.asarray(render, np.float64)
    target = np.asarray(target, np.float64)
    if name == "si_mse":
        scale = render.mean()
        a = render / scale
        err = a - target / target.mean()
        return float(np.mean(err**2)), 2.0 / (render.size * scale) * (err - np.mean(err * a))
    if name in ("l1_joint", "l1_weighted"):
        w = weight if name == "l1_weighted" else 1.0
        return float(w * np.mean(np.abs(render - target))), w * np.sign(render - target) / render.size
    raise ValueError(f"unknown loss {name!r}")


def views_for_step(schedule: str, step: int, n_views: int) -> list[int]:
    """Which views a step back-propagates: one, cycling (i_t = t mod n), or all."""
    if schedule == "cyclic":
        return [step % n_views]
    if schedule == "joint":
        return list(range(n_views))
    raise ValueError(f"unknown schedule {schedule!r}")
