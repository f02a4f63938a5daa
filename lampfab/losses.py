"""The source's per-view losses and view schedules.

Written with arithmetic and a ``mean`` function only, so the same code runs on Dr.Jit
tensors (for gradients) and on numpy arrays (tests, reports).
"""

from __future__ import annotations

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


def views_for_step(schedule: str, step: int, n_views: int) -> list[int]:
    """Which views a step back-propagates: one, cycling (i_t = t mod n), or all."""
    if schedule == "cyclic":
        return [step % n_views]
    if schedule == "joint":
        return list(range(n_views))
    raise ValueError(f"unknown schedule {schedule!r}")
