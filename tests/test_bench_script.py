"""bench/bench_methods.py (`make bench`) measures the source's method with the default LED;
bench/slope_projection.py replays a refinement's slope projections under two solvers."""

import dataclasses

import pytest

from tests.helpers import ROOT, load_script


def test_the_source_method_runs_with_the_default_posts_leds(tmp_path, tiny_profile):
    # lampfab refuses ptracer for a maker's flat LEDs; the benchmark, which measures that
    # method, failed on it once the post became the default LED.
    from lampfab import optimize, pipeline
    from lampfab.errors import LampfabError

    bench = load_script("bench/bench_methods.py")
    build = pipeline.Build.open(tmp_path / "b", str(tiny_profile), "sla_resin", "post3535")
    pipeline.prepare(build, str(ROOT / "examples" / "apple.png"), {})
    inner = build.inner()
    opt = dataclasses.replace(build.design.optimize, method="ptracer", loss="si_mse", schedule="cyclic",
                              backtrack=False)
    with pytest.raises(LampfabError, match='method "ptracer"'):
        build.optimizer(opt, inner, build.targets(opt.sensor_px))
    runner = bench.optimizer(build, inner, opt)
    assert isinstance(runner, optimize.PtracerOptimizer)
    assert runner.source.shape == "post" and runner.source.radius_mm == 0.0  # a point at the LED's place


def test_the_slope_projection_benchmark_replays_under_both_solvers(cyl):
    """The same projections under the transforms' solver and the sparse LU: the same
    passes and surfaces, and the projection's own solver back in place afterwards."""
    import numpy as np

    from lampfab import limits

    bench = load_script("bench/slope_projection.py")
    heights = np.zeros((64, 17))
    heights[10:14, 6:10] = 8.0                          # far steeper than 45°
    calls = [((cyl, heights, 45.0), {}), ((cyl, heights * 0.5, 45.0), {"max_overhang_deg": 45.0})]
    own = bench.replay(calls, lambda diff, solver: solver)
    lu = bench.replay(calls, lambda diff, solver: bench._SparseLU(diff))
    assert own[0] == lu[0] and min(own[0]) > 0
    for x, y in zip(own[2], lu[2], strict=True):
        assert np.allclose(x, y, atol=1e-9)
    assert isinstance(limits._edge_system(64, 17)[3], limits._GridLaplacian)


def test_the_ssim_regions_split_a_wall_and_find_a_veil_on_its_black():
    """bench/ssim_regions.py: the five regions tile the wall, and a faint veil added to
    a perfect picture costs SSIM where the wall is black and far from the picture."""
    import numpy as np

    from lampfab import metrics

    bench = load_script("bench/ssim_regions.py")
    y, x = np.mgrid[0:48, 0:64]
    target = np.clip((16 - np.hypot(x - 32, y - 24)) / 4, 0, 1)  # a flat bright disc, a soft rim, black around
    masks = bench.regions(target)
    assert sum(m.astype(int) for m in masks.values()).max() == 1 == sum(m.astype(int) for m in masks.values()).min()
    assert all(m.any() for m in masks.values())
    veiled = target + 0.01 * target.max()
    found = bench.wall_regions(target, {"reference": target, "LED render": veiled, "direct": target})
    assert found["far black"]["reference"] == 1.0 and found["bright interior"]["LED render"] > 0.98
    assert found["far black"]["LED render"] < 0.7 and found["ripple"] == 0.0
    cost = {n: r["share"] * (r["reference"] - r["LED render"]) for n, r in found.items() if n != "ripple"}
    assert sum(cost.values()) == pytest.approx(1.0 - metrics.ssim(veiled, target), abs=1e-12)
    assert max(cost, key=cost.get) == "far black"


def test_the_facet_walk_benchmark_finds_the_facets_mitsuba_finds(tmp_path, tiny_profile):
    """bench/facet_walk.py on a tiny build's bumpy first design: both searches run on the
    same photons, and they agree on nearly every facet."""
    import numpy as np

    from lampfab import pipeline

    bench = load_script("bench/facet_walk.py")
    build = pipeline.Build.open(tmp_path / "b", str(tiny_profile), "sla_resin", "post3535")
    apple = str(ROOT / "examples" / "apple.png")
    pipeline.snapshot(build, {"all": apple})
    pipeline.prepare(build, apple, {})
    opt = build.design.optimize
    heights = 2.0 + np.random.default_rng(5).normal(scale=0.3, size=(opt.grid_u, opt.grid_v))
    np.savez(build.out / "init.npz", heights=heights)
    row = bench.measure(build.out, repeats=1)
    assert row["with flux"] > 0.5 * row["photons"]
    assert row["same"] > 0.999 * row["with flux"]
    assert row["bvh_s"] > 0 and row["walk_s"] > 0
    assert "| b | " in bench.report([row], 1)
