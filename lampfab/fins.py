"""Where a post's matt black fins stop light.

A post (``source.Source`` of shape "post") may have fins: vertical half-planes from the
lamp's axis at the edges of its LEDs' sectors (``Source.fin_azimuths_deg``),
``fin_radius_mm`` out and ``fin_height_mm`` tall, centred on the LEDs' height.  They
stop light wherever it crosses the cavity: as it leaves an LED towards a neighbour's
sector, and when a reflection at the cavity's wall or the outer surface sends it back
across the cavity into another sector (on the default apple that was half the
reflected light on its left and right walls: bench/log).
"""

from __future__ import annotations

import numpy as np


def stops(mi, source, o, d, t_max=None):
    """Dr.Jit Bool per ray: the rays from ``o`` (Dr.Jit Point3f, mm) along unit ``d``
    (Vector3f) that meet one of ``source``'s fins before ``t_max`` (Dr.Jit Float, mm;
    None: anywhere ahead).  All False for a source without fins."""
    import drjit as dr

    stopped = dr.zeros(mi.Bool, dr.width(d))
    if not source.fins:
        return stopped
    p = o - mi.Point3f(*source.position_mm)
    for a in np.radians(source.fin_azimuths_deg()):
        along = mi.Vector3f(float(np.cos(a)), float(np.sin(a)), 0.0)
        across = mi.Vector3f(float(-np.sin(a)), float(np.cos(a)), 0.0)
        # A ray parallel to the fin gives an infinite t, which no test below accepts.
        t = -dr.dot(p, across) / dr.dot(d, across)
        hit = p + t * d
        reach = dr.dot(hit, along)
        ahead = (t > 0) if t_max is None else ((t > 0) & (t < t_max))
        stopped |= (ahead & (reach > 0) & (reach <= source.fin_radius_mm)
                    & (dr.abs(hit.z) <= 0.5 * source.fin_height_mm))
    return stopped


def stopper(mi, source):
    """``stops`` for ``source`` as ``trace.propagate``'s ``stops(o, d, t_max)``, or None
    when nothing stops light (no source, or one without fins)."""
    if source is None or not source.fins:
        return None
    return lambda o, d, t_max: stops(mi, source, o, d, t_max)
