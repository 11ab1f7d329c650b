"""Conventions a contributor runs, as scikit-learn's ``check_estimator``: the checks every
registered surface model and extraction method passes, on a new one before it is added::

    from vetica_cli.testing import check_method, check_surface_model

    check_surface_model(surfaces.get("kelvin-voigt"))   # declarations, theory, kernel, config, a short run
    check_method(extraction.get("peak-force"))          # declarations, options, a run on a record

Each raises ``AssertionError`` naming what is missing.  A method is checked on a record of a
surface model it declares (its first registered one; a model-free method: the default model),
simulated once per model and process with the model's defaults and cheap numerics
(:data:`CHEAP`: 3 recorded periods at 1 ns, dt 0.05 ns).  ``tests/test_registries.py`` runs
both on every registered model and method: a new one is checked without editing a test.
"""

from __future__ import annotations

import copy
import functools
import json
import math
import re

import numpy as np

from . import surfaces
from .errors import ConfigError, InputError

# cheap numerics of the check's records: a few periods, coarse print step, a firm controller
CHEAP = {"numerics.dt": 0.05e-9, "numerics.print_step": 1e-9, "numerics.record_cycles": 3, "numerics.max_time": 0.002,
         "numerics.kp": 0.05, "numerics.ki": 0.03}  # fmt: skip


def check_surface_model(model, simulate: bool = True, declarations_only: bool = False) -> None:
    """Every convention of :mod:`vetica_cli.surfaces.base` on ``model`` (a registered model or
    a specialisation of one): its declarations (:func:`~vetica_cli.surfaces.base.convention_errors`),
    theory values for every quantity, the kernel's arms or its own kernel, log-gradients, fit
    bounds around its defaults, its config section validated by its rules and round-tripped,
    and -- with ``simulate`` -- a short run to a steady record with its columns.
    ``declarations_only``: the declarations alone (a specialised model, e.g. a Wiechert
    surface of three arms, whose defaults are the registered model's)."""
    from .simulation.config import from_dict

    errors = surfaces.base.convention_errors(model)
    assert not errors, f"surface model {model.key!r} needs: " + "; ".join(errors)
    if declarations_only:
        return
    params = model.parse({})
    assert set(params) == set(model.config_keys), "parse({}) gives every config key"
    th = model.theory(params)
    assert list(th) == list(model.quantities), "theory(): every quantity, in table order"
    assert all(isinstance(v, float) and math.isfinite(v) for v in th.values()), "theory(): finite floats"
    k_inf, k, cd = model.kernel_arms(params)
    assert isinstance(k_inf, float) and k_inf > 0, "kernel_arms(): k_inf > 0"
    assert k.ndim == cd.ndim == 1 and len(k) == len(cd) >= 1 and k.dtype == cd.dtype == np.float64
    assert np.all(k > 0) and np.all(cd > 0), "kernel_arms(): positive arms"
    grads = model.log_gradients(params)
    assert set(grads) == set(model.quantities), "log_gradients(): every quantity"
    assert all(len(g) == len(model.parameter_keys) for g in grads.values()), "log_gradients(): one per parameter"
    for p in model.parameter_keys:
        if p in grads:
            assert grads[p] == tuple(1.0 if q == p else 0.0 for q in model.parameter_keys), f"d ln {p}/d ln {p} = 1"
    for p, (lo, hi) in model.fit_bounds.items():
        if isinstance(params.get(p), float):
            assert lo < params[p] < hi, f"fit_bounds of {p} around its default"
    for name, (pred, allowed) in model.rules.items():
        if not pred(-1.0):
            try:
                from_dict({"surface": {"model": model.key, name: -1.0}})
            except ConfigError as exc:
                assert re.search(rf"surface\.{name}: -1.0 is not allowed; expected", str(exc)), str(exc)
            else:
                raise AssertionError(f"surface.{name}: -1 passed its rule")
    cfg = from_dict({"surface": {"model": model.key}})
    assert cfg.surface.model == model.key and from_dict(cfg.to_dict()) == cfg, "the surface section round-trips"
    if simulate:
        df, meta = record_of(model.key)
        assert {"t", "z_tip", "f_ts", "z_paddle", "segment", *model.extra_columns} <= set(df.columns)
        assert meta["stop_reason"].startswith("steady"), meta["stop_reason"]


@functools.lru_cache(maxsize=None)
def _record(model_key: str):
    from .simulation.config import load
    from .simulation.simulate import simulate

    run = simulate(load(None, {"surface.model": model_key, **CHEAP}))
    return run.frame(), run.metadata()


def record_of(model_key: str):
    """``(run table, metadata)`` of a short simulated record of ``model_key`` (:data:`CHEAP`),
    once per model and process."""
    df, meta = _record(model_key)
    return df.copy(), copy.deepcopy(meta)


def model_for(method) -> str:
    """The surface model a method is checked on: its first declared model in registry order
    (the default model when it declares every one)."""
    models = tuple(method.surface_models)
    if surfaces.DEFAULT_MODEL in models and len(models) == len(surfaces.MODELS):
        return surfaces.DEFAULT_MODEL
    return next(k for k in surfaces.MODELS if k in models)


def check_method(method, model_key: str | None = None) -> None:
    """Every convention of :mod:`vetica_cli.extraction.base` on ``method``: its declarations
    (:func:`~vetica_cli.extraction.base.convention_errors`), its options (defaults complete,
    an unknown option refused in one line), and a run on a record of ``model_key`` (default:
    :func:`model_for`) through :func:`vetica_cli.extraction.extract` with the true force: a
    typed result with the quantities it declares for that model in order, units, signed errors,
    error bars and checks applied, a JSON object and a text table."""
    from .extraction import ExtractionResult, extract
    from .extraction.base import convention_errors
    from .extraction.format import format_table, to_json

    errors = convention_errors(method)
    assert not errors, f"method {method.key!r} needs: " + "; ".join(errors)
    assert method.options({}) == method.options_default, "options({}) gives the declared defaults"
    try:
        method.options({"nope": 1})
    except InputError as exc:
        assert f"method {method.key!r} takes no option 'nope'" in str(exc), str(exc)
    else:
        raise AssertionError("an unknown option passed")
    key = model_key or model_for(method)
    df, meta = record_of(key)
    res = extract(df, meta, force="true", method=method.key)
    assert isinstance(res, ExtractionResult) and res.method == method.key and res.force == "true"
    qs = method.quantities(surfaces.get(res.model))
    assert list(res.estimates)[: len(qs)] == list(qs), "the declared quantities, in order"
    for name, e in res.estimates.items():
        if name in qs:
            assert e.unit == qs[name].unit, f"{name}: its declared unit"
        if e.value is not None and e.theory:
            assert math.isclose(e.error_pct, 100 * (e.value - e.theory) / e.theory, rel_tol=1e-9), f"{name}: signed error"
    assert "uncertainty" in res.info and "sanity" in res.info, "error bars and checks applied"
    out = to_json(res)
    json.dumps(out, allow_nan=False)
    assert {"force", "taps", "method", "info"} <= set(out)
    assert all({"value", "theory", "error_pct", "spread"} <= set(out[n]) for n in res.estimates)
    assert format_table(res).startswith(method.title), "the text table starts with the title"
