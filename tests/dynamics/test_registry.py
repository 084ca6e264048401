"""Tests of knotmm.dynamics.registry: every entry builds, steps, and has the order it declares."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from knotmm.config import SCHEMA, RunConfig
from knotmm.dynamics.brownian import StochasticIntegrator
from knotmm.dynamics.deterministic import Integrator
from knotmm.dynamics.registry import (
    BROWNIAN_NAMES,
    NAMES,
    REGISTRY,
    integrator_from_config,
    make,
    resolve,
)
from knotmm.errors import ConfigError

RATES = np.array([0.5, 1.0, 2.0, 3.0])  # one decay rate per bead: dy/dt = -lambda y
Y0 = np.array([[1.0, -0.5, 0.25], [0.3, 0.8, -1.2], [-0.7, 0.1, 0.9], [1.5, -1.0, 0.4]])
T_END = 2.0


def _rhs(y):
    return -RATES[:, None] * y


def _exact(t):
    return np.exp(-RATES[:, None] * t) * Y0


def _fixed_steps(name, h):
    """The integrator with steps of exactly ``h`` (adaptive ones: huge tolerance, cap h)."""
    info = REGISTRY[name]
    if info.adaptive:
        return make(name, h, tolerance=1e12, max_timestep=h)
    return make(name, h)


def _global_error(integrator, h):
    y, t = Y0.copy(), 0.0
    for _ in range(round(T_END / h)):
        y, dt = integrator.step(_rhs, y, T_END - t)
        assert dt == pytest.approx(h, rel=1e-12)
        t += dt
    assert t == pytest.approx(T_END, rel=1e-12)
    return float(np.max(np.abs(y - _exact(T_END))))


@pytest.mark.parametrize("name", NAMES)
def test_entry_matches_its_class(name):
    info = REGISTRY[name]
    cls = info.load()
    assert issubclass(cls, Integrator) and cls.name == name
    assert issubclass(cls, StochasticIntegrator) == info.brownian == (name in BROWNIAN_NAMES)
    assert cls.adaptive == info.adaptive
    declared = cls.weak_order if info.brownian else cls.order
    assert declared == info.order
    assert info.description and "\n" not in info.description
    assert info.default_timestep > 0


@pytest.mark.parametrize("name", NAMES)
def test_every_entry_builds_and_steps_a_small_problem(name):
    info = REGISTRY[name]
    pecl = [math.inf, 2.0] if info.brownian else [math.inf]
    for peclet in pecl:
        integ = make(name, info.default_timestep, peclet=peclet, seed=3)
        assert isinstance(integ, info.load())
        y, dt = integ.step(_rhs, Y0.copy(), 1.0)
        assert y.shape == Y0.shape and np.all(np.isfinite(y))
        assert 0 < dt <= info.default_timestep
        # a small step moves the chain by about h v (noise aside: sqrt(2 kT h) per coordinate)
        scale = dt * np.abs(_rhs(Y0)).max() + (6 * math.sqrt(2 * dt / peclet))
        assert np.max(np.abs(y - Y0)) <= scale + 1e-12


@pytest.mark.parametrize("name", NAMES)
def test_declared_order_on_a_linear_problem(name):
    """Global error at t = 2 against exp(-lambda t): halving h divides it by 2**order.

    Brownian entries are measured in their deterministic limit (Pe = inf), where
    euler_maruyama is Euler (order 1) and ito_heun is Heun (order 2): at least their
    declared (weak) order.
    """
    info = REGISTRY[name]
    hs = [T_END / n for n in (40, 80, 160)]
    errs = [_global_error(_fixed_steps(name, h), h) for h in hs]
    slope = float(np.log(errs[-2] / errs[-1]) / np.log(2.0))
    if info.brownian:
        assert slope >= info.order - 0.1, (errs, slope)
    else:
        assert slope == pytest.approx(info.order, abs=0.1), (errs, slope)


def test_auto_policy_and_default_steps():
    assert resolve("auto", math.inf, None) == ("rk23", 0.01)
    assert resolve("auto", 2.0, None) == ("ito_heun_adaptive", 0.002)
    assert resolve("leimkuhler_matthews", 2.0, None) == ("leimkuhler_matthews", 0.01)
    assert resolve("ito_heun", 2.0, None) == ("ito_heun", 0.002)
    assert resolve("euler_maruyama", 2.0, None) == ("euler_maruyama", 0.002)
    assert resolve("ito_heun", math.inf, None) == ("ito_heun", 0.01)  # no noise: as heun
    assert resolve("heun", math.inf, None) == ("heun", 0.01)
    assert resolve("auto", 2.0, 1e-3) == ("ito_heun_adaptive", 1e-3)
    with pytest.raises(ConfigError, match="run.integrator = 'rk4'"):
        resolve("rk4", math.inf, None)


def test_config_validates_integrators_through_the_registry():
    assert SCHEMA["run"]["integrator"].choices == ("auto", *NAMES)
    with pytest.raises(ConfigError, match="run.integrator"):
        RunConfig.from_dict({"run": {"integrator": "rk4"}})
    for name in NAMES:
        cfg = RunConfig.from_dict({"run": {"integrator": name}})
        assert type(integrator_from_config(cfg)) is REGISTRY[name].load()


def test_make_refuses_what_cannot_run():
    with pytest.raises(ConfigError, match="run.integrator = 'rk23' cannot integrate Brownian"):
        make("rk23", 0.01, peclet=2.0)
    with pytest.raises(ConfigError, match="run.timestep"):
        make("ito_heun", 0.0, peclet=2.0)
    with pytest.raises(ConfigError, match="run.integrator = 'euler'.*timestep"):
        make("euler", -1.0)
    with pytest.raises(ConfigError, match="run.peclet"):
        make("ito_heun", 0.002, peclet=-1.0)


def test_config_import_stays_light():
    """The registry imports integrator classes only when one is built."""
    code = "import sys, knotmm.config; print(sorted({'numba', 'scipy'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
