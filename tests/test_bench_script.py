"""bench/bench_methods.py (`make bench`) measures the source's method with the default LED."""

import dataclasses
import importlib.util
import sys

import pytest

from tests.helpers import ROOT


def _load():
    spec = importlib.util.spec_from_file_location("bench_methods", ROOT / "bench" / "bench_methods.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_the_source_method_runs_with_the_default_posts_leds(tmp_path, tiny_profile):
    # lampfab refuses ptracer for a maker's flat LEDs; the benchmark, which measures that
    # method, failed on it once the post became the default LED.
    from lampfab import optimize, pipeline
    from lampfab.errors import LampfabError

    bench = _load()
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
