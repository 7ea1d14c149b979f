"""Monte Carlo studies of the method: simulated campaigns identified and compared with their truth.

A study plan is a simulation configuration (the tables of :mod:`jointid.app.synthesis`:
``[campaign]``, ``[[model]]``, ``[excitation]``, ``[acquisition]``) with three more tables::

    [study]
    name = "uncertainty calibration"
    campaigns = 200                 # campaigns per grid point
    seed = 2026                     # study seed: campaign i draws from child i of SeedSequence(seed)

    [identify]                      # fields of IdentifySettings (optional)
    terms = "q + -q^3 + q'"
    damping_order = 2

    [vary]                          # one draw per campaign; keys are dotted paths into the tables
    "acquisition.noise" = { loguniform = [0.001, 0.02] }
    "model.coefficients.k3" = { uniform = [3e6, 6e6], random_sign = true }
    "excitation.force_levels" = { uniform = [0.4, 2.0], size = [2, 4] }   # 2 to 4 sorted levels
    "acquisition.fs" = { uniform = [1500.0, 4000.0] }
    "acquisition.periods" = { integers = [10, 40] }
    "acquisition.write_frequency" = { choice = [true, false] }   # frequency given or not

    [grid]                          # every combination is a grid point with `campaigns` campaigns
    "excitation.n_frequencies" = [9, 21]

Distributions: ``uniform = [low, high]``, ``loguniform = [low, high]``, ``normal = [mean, std]``,
``integers = [low, high]`` (both included), ``choice = [v1, v2, ...]``; options ``random_sign``
(a random sign for the value) and ``size`` (a sorted list of that many draws, or of a number of
draws between ``[min, max]``).  A path through a list of tables (``model.omega1`` with several
``[[model]]``) sets the key in each of them; an integer picks one (``model.1.omega1``) or one
element of a list (``model.amplitude_laws.c.2``).

Campaign ``i`` belongs to grid point ``i % n_points``; its seed is the integer state of child
``i`` of ``numpy.random.SeedSequence(seed)``, from which its draws and its noise follow (the
plan's ``acquisition.seed`` is replaced by a seed drawn from the campaign's), so a
campaign is reproduced from its seed alone and a study can be extended (more campaigns) or
resumed (``campaigns.jsonl`` is appended to; campaigns already there are skipped).

Each campaign is simulated by harmonic balance into a temporary folder, identified with
:func:`~jointid.app.workflow.identify_campaign` and compared with its truth by
:func:`comparison_rows`: estimate, standard error, 95 % interval and truth of every parameter
that the results give.  :func:`study_statistics` turns the rows into bias, RMSE, std(z) with
``z = (estimate - truth) / stderr`` and the 95 % coverage per parameter.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import html
import json
import math
import os
import tempfile
import warnings
from dataclasses import dataclass, field, fields, replace
from itertools import product
from pathlib import Path

import numpy as np

from ..errors import JointidError, JointidWarning, ManifestError, unknown_key_message
from .records import IdentifySettings
from .synthesis import _INF, _SPECS, _TABLES, MAX_SEED, _check_value, _describe, _is_number, check_campaign_size
from .synthesis import check_simulation_tables as _check_simulation_tables

__all__ = [
    "StudyPlan",
    "StudyResult",
    "load_study_plan",
    "run_campaign",
    "run_study",
    "campaign_truth",
    "comparison_rows",
    "study_statistics",
    "read_campaign_lines",
    "check_study_folder",
    "remove_stale_scratch",
    "StudyInterrupted",
]

RESULTS_FILE = "campaigns.jsonl"

_DISTRIBUTIONS = ("uniform", "loguniform", "normal", "integers", "choice")
_OPTIONS = ("random_sign", "size")
_RUN_ONLY = ("jobs", "scheduler", "progress")  # IdentifySettings fields a plan does not set (a campaign runs serially)


# ----------------------------------------------------------------------------------------------------------
# plan


def _settings_names() -> tuple:
    return tuple(f.name for f in fields(IdentifySettings) if f.name not in _RUN_ONLY)


def _check_path(path, source, what):
    parts = path.split(".")
    if parts[0] not in _TABLES:
        raise ManifestError(f"{source}: [{what}] {path!r}: {unknown_key_message(parts[0], _TABLES, 'table')}")
    rest = [p for p in parts[1:] if not p.lstrip("-").isdigit()]
    if not rest:
        raise ManifestError(f"{source}: [{what}] {path!r} names a table, not a value")
    if rest[0] not in _TABLES[parts[0]]:
        raise ManifestError(f"{source}: [{what}] {path!r}: {unknown_key_message(rest[0], _TABLES[parts[0]])}")


def _check_distribution(path, spec, source):
    where = f"{source}: [vary] {path!r}"
    if not isinstance(spec, dict):
        raise ManifestError(f"{where}: expected a table such as {{ uniform = [0.001, 0.02] }}, got {spec!r}")
    kinds = [k for k in spec if k in _DISTRIBUTIONS]
    for k in spec:
        if k not in _DISTRIBUTIONS + _OPTIONS:
            raise ManifestError(f"{where}: {unknown_key_message(k, _DISTRIBUTIONS + _OPTIONS)}")
    if len(kinds) != 1:
        raise ManifestError(f"{where}: exactly one of {', '.join(_DISTRIBUTIONS)} expected, got {kinds or 'none'}")
    kind = kinds[0]
    args = spec[kind]
    if not isinstance(args, list) or not args:
        raise ManifestError(f"{where}: {kind} needs a non-empty list, got {args!r}")
    if kind != "choice":
        if len(args) != 2 or not all(isinstance(a, (int, float)) and np.isfinite(a) for a in args):
            raise ManifestError(f"{where}: {kind} needs two finite numbers, got {args!r}")
        lo, hi = args
        if kind == "loguniform" and not 0 < lo <= hi:
            raise ManifestError(f"{where}: loguniform needs 0 < low <= high, got {args!r}")
        if kind in ("uniform", "integers") and lo > hi:
            raise ManifestError(f"{where}: {kind} needs low <= high, got {args!r}")
        if kind == "normal" and hi < 0:
            raise ManifestError(f"{where}: normal needs a non-negative standard deviation, got {hi!r}")
    size = spec.get("size")
    if size is not None:
        ok = (isinstance(size, int) and size >= 1) or (
            isinstance(size, list) and len(size) == 2 and all(isinstance(s, int) for s in size) and 1 <= size[0] <= size[1])
        if not ok:
            raise ManifestError(f"{where}: size must be a positive integer or [min, max], got {size!r}")


# bounds of a plan that a 2-core / 24 GiB machine runs (stated in docs/formats.md, "Study plan")
MAX_CAMPAIGNS = 100_000  # campaigns of a study, all grid points together
MAX_GRID_POINTS = 1_000
# the size of one campaign: jointid.app.synthesis.MAX_CAMPAIGN_RECORDS and MAX_RECORD_SAMPLES


def _path_spec(path):
    """The spec of the value at a dotted path (``None``: a path the specs do not cover)."""
    parts = path.split(".")
    keys = [p for p in parts[1:] if not p.lstrip("-").isdigit()]
    spec = _SPECS.get((parts[0], keys[0])) if keys else None
    if spec is None:
        return None
    after = parts[parts.index(keys[0]) + 1:]  # what follows the key: a name in a table, an index in a list
    for p in after:
        if spec[0] == "table" and not p.lstrip("-").isdigit():
            spec = spec[1]
        elif spec[0] == "list" and p.lstrip("-").isdigit():
            spec = spec[1]
        else:
            return ("none", p)
    return spec


def _check_draw_against_key(path, spec, source):
    """A [vary] distribution must draw values its key takes: type, bounds, ``size`` only on a list."""
    where = f"{source}: [vary] {path!r}"
    target = _path_spec(path)
    if target is None:
        return
    if target[0] == "none":
        raise ManifestError(f"{where}: {target[1]!r} is below a value, not a table or a list")
    kind = next(k for k in spec if k in _DISTRIBUTIONS)
    args = spec[kind]
    size = spec.get("size")
    if size is not None:
        if target[0] != "list":
            raise ManifestError(f"{where}: size draws a list, but the key takes {_describe(target)}")
        most = size if isinstance(size, int) else size[1]
        if most > target[3]:
            raise ManifestError(f"{where}: size draws up to {most} values, at most {target[3]} allowed")
        target = target[1]
    if kind == "choice":
        kinds = {("number" if _is_number(a) else type(a).__name__) for a in args}
        if len(kinds) > 1:
            raise ManifestError(f"{where}: choice values must all be of one type, got {sorted(kinds)} in {args!r}"[:300])
        for a in args:
            _check_value(target, a, f"{where}: choice value")
        return
    if target[0] not in ("number", "int", "label"):
        raise ManifestError(f"{where}: {kind} draws numbers, but the key takes {_describe(target)}")
    if target[0] == "int" and kind != "integers":
        raise ManifestError(f"{where}: {kind} draws fractions, but the key takes {_describe(target)}; use integers")
    ends = list(args) if kind != "normal" else [args[0] - 5 * args[1], args[0] + 5 * args[1]]
    if spec.get("random_sign"):
        ends += [-a for a in ends]
    for a in ends:
        if kind == "integers" and target[0] == "int":
            a = int(a)
        _check_value(target, a, f"{where}: {kind} {'mean +- 5 std' if kind == 'normal' else 'bound'}")


def _candidates(simulation, vary, grid, path, counts=False):
    """Values a key can take over the campaigns (the static value, the grid values, the draws' ends).

    With ``counts``: lengths of the list it can hold (a ``size`` draw's largest count)."""
    table, key = path.split(".")
    out = []
    for t in (simulation.get(table) if isinstance(simulation.get(table), list) else [simulation.get(table) or {}]):
        if key in t:
            out.append(t[key])
    for p, values in grid:
        if p == path:
            out.extend(values)
    for p, spec in vary:
        if p != path:
            continue
        kind = next(k for k in spec if k in _DISTRIBUTIONS)
        args = spec[kind]
        size = spec.get("size")
        ends = list(args) if kind != "normal" else [args[0]]
        if spec.get("random_sign"):
            ends = [abs(a) if _is_number(a) else a for a in ends]
        if size is not None:  # a list of up to `most` draws between the ends
            most = size if isinstance(size, int) else size[1]
            out.append([ends[min(j, len(ends) - 1)] for j in range(most)] if counts else ends)
        else:
            out.extend(ends)
    if counts:
        return [len(v) for v in out if isinstance(v, list)]
    return [v for v in out if _is_number(v)] + [x for v in out if isinstance(v, list) for x in v if _is_number(x)]


def _check_campaign_size(simulation, vary, grid, source):
    """Records per campaign and samples per record stay within what one worker simulates and identifies."""
    def c(path, default):
        vals = _candidates(simulation, vary, grid, path)
        return vals or [default]

    models = simulation.get("model")
    n_models = len(models) if isinstance(models, list) else 1
    n_levels = max(_candidates(simulation, vary, grid, "excitation.force_levels", counts=True) or [1])
    n_freq = max(c("excitation.n_frequencies", 41) + _candidates(simulation, vary, grid, "excitation.frequencies_hz",
                                                                  counts=True))
    f_low = min([w / (2 * math.pi) for w in c("excitation.omega_start", _INF) + c("excitation.omega_stop", _INF)]
                + _candidates(simulation, vary, grid, "excitation.frequencies_hz") + [_INF])
    fs, periods = max(c("acquisition.fs", 5000.0)), max(c("acquisition.periods", 20.0))
    check_campaign_size(n_models, n_levels, n_freq, fs, periods, f_low, source)


def _check_identify_table(ident, source):
    """Values of ``[identify]`` that IdentifySettings takes without a check: the terms, the flags, the delay."""
    from ..identify.terms import library
    from .model_checks import is_auto

    terms = ident.get("terms", "q + -q^3 + q'")
    if not isinstance(terms, str):
        raise ManifestError(f"{source}: [identify] terms must be a string such as \"q - q^3 + q'\", got {terms!r}")
    if not is_auto(terms):
        try:
            names = library(terms).names
        except Exception as exc:  # noqa: BLE001 - any parse failure of the plan's text is a bad key
            raise ManifestError(f"{source}: [identify] terms {terms!r}: {exc}") from None
        if "q" not in names:
            raise ManifestError(f"{source}: [identify] terms {terms!r} have no linear stiffness term 'q' (omega1 is "
                                f"its coefficient)")
    for k in ("refine_frequency", "repredict", "keep_flagged"):
        if k in ident and not isinstance(ident[k], bool):
            raise ManifestError(f"{source}: [identify] {k} must be true or false, got {ident[k]!r}")
    delay = ident.get("channel_delay")
    if not (delay is None or delay == "estimate" or (_is_number(delay) and math.isfinite(delay))):
        raise ManifestError(f"{source}: [identify] channel_delay must be \"estimate\" or a finite number of seconds, "
                            f"got {delay!r}")


MAX_LOCAL_JOBS = 64  # worker processes of a local cluster (each holds its own interpreter and tables)


def check_study_jobs(jobs) -> int:
    """``jobs`` of :func:`run_study`: an integer from 0 (one per core) to :data:`MAX_LOCAL_JOBS`."""
    if isinstance(jobs, bool) or not isinstance(jobs, (int, np.integer)) or not 0 <= jobs <= MAX_LOCAL_JOBS:
        raise ManifestError(f"--jobs (jobs) must be an integer from 0 (one per core) to {MAX_LOCAL_JOBS} worker "
                            f"processes of a local cluster, got {jobs!r}; a larger cluster is given with --scheduler")
    return int(jobs)


def _plan_integer(study, key, default, low, high, source):
    v = study.get(key, default)
    if isinstance(v, bool) or not isinstance(v, int):
        raise ManifestError(f"{source}: [study] {key} must be an integer from {low} to {high}, got {v!r}")
    if v < low:
        raise ManifestError(f"{source}: [study] {key} must be at least {low}, got {v!r}")
    if v > high:
        raise ManifestError(f"{source}: [study] {key} must be at most {high} (a study one machine runs), got {v!r}")
    return v


def _draw(spec, rng):
    kind = next(k for k in spec if k in _DISTRIBUTIONS)
    args = spec[kind]
    size = spec.get("size")
    n = None
    if size is not None:
        n = int(size) if isinstance(size, int) else int(rng.integers(size[0], size[1] + 1))

    def one(m):
        if kind == "uniform":
            v = rng.uniform(args[0], args[1], m)
        elif kind == "loguniform":
            v = np.exp(rng.uniform(np.log(args[0]), np.log(args[1]), m))
        elif kind == "normal":
            v = rng.normal(args[0], args[1], m)
        elif kind == "integers":
            v = rng.integers(int(args[0]), int(args[1]) + 1, m)
        else:
            return [args[int(j)] for j in rng.integers(0, len(args), m)]
        if spec.get("random_sign"):
            v = v * rng.choice((-1, 1), m)
        return v.tolist()

    values = one(1 if n is None else n)
    if n is None:
        return values[0]
    return sorted(values)


def _set_path(tables, path, value):
    """Set ``value`` at a dotted path; a non-integer key applied to a list sets it in every element."""

    def walk(node, parts):
        key = parts[0]
        if isinstance(node, list):
            if key.lstrip("-").isdigit():
                j = int(key)
                if len(parts) == 1:
                    node[j] = value
                else:
                    walk(node[j], parts[1:])
            else:
                for item in node:
                    walk(item, parts)
            return
        if not isinstance(node, dict):
            raise ManifestError(f"{path!r}: {key!r} is below a value, not a table")
        if len(parts) == 1:
            node[key] = value
        else:
            if key not in node:
                node[key] = {}
            walk(node[key], parts[1:])

    try:
        walk(tables, path.split("."))
    except IndexError as exc:
        raise ManifestError(f"{path!r}: index out of range") from exc


@dataclass(frozen=True)
class StudyPlan:
    """A Monte Carlo study: base simulation, draws, grid, identification settings.

    Build one with :func:`load_study_plan` (TOML file) or :meth:`from_mapping` (a dict of the
    same tables).  The plan is plain data: it travels to dask workers with each campaign.
    """

    name: str
    campaigns: int
    seed: int
    simulation: dict = field(repr=False)  # campaign / model / excitation / acquisition tables
    vary: tuple = ()  # (path, distribution table)
    grid: tuple = ()  # (path, values)
    settings: IdentifySettings = IdentifySettings()
    source: str = "plan"

    @classmethod
    def from_mapping(cls, d: dict, source="plan") -> "StudyPlan":
        """Parse the tables of a plan (see the module documentation)."""
        if not isinstance(d, dict):
            raise ManifestError(f"{source}: a study plan is a table, got {type(d).__name__}")
        top = ("study", "identify", "vary", "grid") + tuple(_TABLES)
        for k in d:
            if k not in top:
                raise ManifestError(f"{source}: {unknown_key_message(k, top, 'table')}")
        for k in ("study", "identify", "vary", "grid"):
            if not isinstance(d.get(k, {}), dict):
                raise ManifestError(f"{source}: [{k}] must be a table, got {type(d[k]).__name__} {d[k]!r}"[:300])
        study = dict(d.get("study", {}))
        for k in study:
            if k not in ("name", "campaigns", "seed"):
                raise ManifestError(f"{source}: [study] {unknown_key_message(k, ('name', 'campaigns', 'seed'))}")
        n = _plan_integer(study, "campaigns", 100, 1, MAX_CAMPAIGNS, source)
        seed = _plan_integer(study, "seed", 0, 0, MAX_SEED, source)
        name = study.get("name", "study")
        if not isinstance(name, str):
            raise ManifestError(f"{source}: [study] name must be a string, got {name!r}")
        ident = dict(d.get("identify", {}))
        for k in ident:
            if k not in _settings_names():
                raise ManifestError(f"{source}: [identify] {unknown_key_message(k, _settings_names())}")
        _check_identify_table(ident, source)
        try:
            settings = IdentifySettings(**ident)
        except (TypeError, ValueError) as exc:
            raise ManifestError(f"{source}: [identify] {exc}") from exc
        _check_simulation_tables(d, source)
        simulation = {k: copy.deepcopy(d[k]) for k in _TABLES if k in d}
        vary = tuple((str(p), dict(s)) if isinstance(s, dict) else (str(p), s) for p, s in dict(d.get("vary", {})).items())
        for p, s in vary:
            _check_path(p, source, "vary")
            _check_distribution(p, s, source)
            _check_draw_against_key(p, s, source)
        grid = []
        n_points = 1
        for p, values in dict(d.get("grid", {})).items():
            _check_path(p, source, "grid")
            if not isinstance(values, list) or not values:
                raise ManifestError(f"{source}: [grid] {p!r} needs a non-empty list of values, got {values!r}"[:300])
            if p in dict(vary):
                raise ManifestError(f"{source}: {p!r} is both in [vary] and in [grid]")
            n_points *= len(values)
            if n_points > MAX_GRID_POINTS:
                raise ManifestError(f"{source}: [grid] has more than {MAX_GRID_POINTS} points (at {p!r}: "
                                    f"{n_points} so far); at most {MAX_GRID_POINTS} allowed")
            spec = _path_spec(p)
            for v in values:
                if spec is not None and spec[0] == "none":
                    raise ManifestError(f"{source}: [grid] {p!r}: {spec[1]!r} is below a value, not a table or a list")
                if spec is not None:
                    _check_value(spec, v, f"{source}: [grid] {p!r} value")
            grid.append((str(p), list(values)))
        if n * n_points > MAX_CAMPAIGNS:
            raise ManifestError(f"{source}: [study] campaigns = {n} per grid point x {n_points} grid points = "
                                f"{n * n_points} campaigns; at most {MAX_CAMPAIGNS} allowed")
        _check_campaign_size(simulation, vary, grid, source)
        plan = cls(name, n, seed, simulation, vary, tuple(grid), settings, source)
        from .synthesis import load_simulation_config

        try:  # the first campaign's configuration must be valid
            load_simulation_config(plan.draw(0)[0], source=source)
        except JointidError:
            raise
        except (TypeError, ValueError, KeyError, IndexError, OverflowError, ZeroDivisionError) as exc:
            raise ManifestError(f"{source}: the first campaign's configuration is not valid: "
                                f"{type(exc).__name__}: {exc}") from None
        return plan

    def mapping(self) -> dict:
        """The plan's tables (JSON-safe), as :meth:`from_mapping` reads them."""
        return {
            "study": {"name": self.name, "campaigns": self.campaigns, "seed": self.seed},
            "identify": {k: getattr(self.settings, k) for k in _settings_names()},
            **copy.deepcopy(self.simulation),
            "vary": {p: s for p, s in self.vary},
            "grid": {p: v for p, v in self.grid},
        }

    @property
    def fingerprint(self) -> str:
        """A hash of everything that makes a campaign, except the number of campaigns."""
        d = self.mapping()
        d["study"].pop("campaigns")
        text = json.dumps(d, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    @property
    def points(self) -> list:
        """The grid points: one dict ``{path: value}`` per combination (``[{}]`` without a grid)."""
        if not self.grid:
            return [{}]
        paths = [p for p, _ in self.grid]
        return [dict(zip(paths, combo)) for combo in product(*(v for _, v in self.grid))]

    @property
    def n_campaigns(self) -> int:
        return self.campaigns * len(self.points)

    def campaign_seed(self, index: int) -> int:
        """Seed of campaign ``index``: the state of child ``index`` of ``SeedSequence(seed)``."""
        child = np.random.SeedSequence(self.seed, spawn_key=(int(index),))
        return int(child.generate_state(1, np.uint64)[0])

    def draw(self, index: int):
        """The simulation tables of campaign ``index``, its drawn values and its grid point.

        Returns
        -------
        tables : dict
            A simulation configuration for :func:`~jointid.app.synthesis.load_simulation_config`.
        drawn : dict
            ``{path: value}`` of the ``[vary]`` draws and the grid point.
        point : int
            Index of the grid point.
        """
        points = self.points
        k = int(index) % len(points)
        rng = np.random.default_rng(self.campaign_seed(index))
        tables = copy.deepcopy(self.simulation)
        drawn = {}
        try:
            for path, value in points[k].items():
                _set_path(tables, path, copy.deepcopy(value))
                drawn[path] = value
            for path, spec in self.vary:
                drawn[path] = _draw(spec, rng)
                target = _path_spec(path)
                if target is not None and target[0] != "none":  # a normal draw beyond 5 std: this campaign fails
                    _check_value(target, drawn[path], f"[vary] {path!r} drew")
                _set_path(tables, path, drawn[path])
        except ManifestError as exc:
            raise ManifestError(f"{self.source}: {exc}") from exc
        tables.setdefault("acquisition", {})
        tables["acquisition"]["seed"] = int(rng.integers(0, 2**63 - 1))
        return tables, drawn, k


def load_study_plan(path) -> StudyPlan:
    """Read a study plan (TOML); see the module documentation for its tables."""
    from ..io.campaign import read_toml

    return StudyPlan.from_mapping(read_toml(path, "study plan"), source=str(path))


# ----------------------------------------------------------------------------------------------------------
# truth and comparisons


def campaign_truth(config) -> dict:
    """The true parameters of a simulated campaign (JSON-safe).

    Parameters
    ----------
    config : SimulationConfig
        As read by :func:`~jointid.app.synthesis.load_simulation_config`.

    Returns
    -------
    dict
        ``preloads``: per preload, the coefficients without an amplitude law and the amplitude
        laws (``{name: [p0, p1, ...]}``); ``records``: per record (in the order the campaign
        writes them) its preload, force level, true ``q_max`` and coefficients at that ``q_max``.
    """
    from .synthesis import simulate_steady_states

    preloads = []
    for preload, model in config.models:
        names = model.terms.coefficient_names
        preloads.append({
            "preload": preload,
            "coefficients": {n: v for n, v in zip(names, model.coefficients) if n not in model.amplitude_laws},
            "laws": {n: list(p) for n, p in model.amplitude_laws.items()},
        })
    models = dict(config.models)
    records = []
    for preload, F, frf in simulate_steady_states(config):
        model = models[preload]
        for state in frf.states:
            records.append({
                "index": len(records), "preload": preload, "force_level": F, "q_max": float(state.q_max),
                "coefficients": dict(zip(model.terms.coefficient_names, model.coefficients_at(state.q_max).tolist())),
            })
    return {"preloads": preloads, "records": records}


def _finite(x):
    return x is not None and isinstance(x, (int, float)) and np.isfinite(x)


def _interval(ci, k=None):
    """``(low, high)`` from a ``*_ci95`` value (a pair, or a list of pairs with ``k``)."""
    if ci is None:
        return None
    try:
        if k is not None:
            ci = ci[k]
        lo, hi = float(ci[0]), float(ci[1])
    except (TypeError, IndexError, KeyError, ValueError):
        return None
    return (lo, hi) if np.isfinite(lo) and np.isfinite(hi) else None


def _row(parameter, where, estimate, stderr, truth, ci=None) -> dict:
    z = None
    if _finite(estimate) and _finite(stderr) and stderr > 0:
        z = (estimate - truth) / stderr
    if not _finite(estimate):
        covered = None
    elif ci is not None:
        covered = bool(ci[0] <= truth <= ci[1])
    else:
        covered = bool(abs(z) <= 1.96) if z is not None else None
    return {"parameter": parameter, "where": where, "estimate": estimate if _finite(estimate) else None,
            "stderr": stderr if _finite(stderr) else None, "ci95": list(ci) if ci else None, "truth": truth,
            "z": z, "covered": covered}


def _law_truth(pre, order):
    """True damping-law coefficients ``c0..c_order`` (None when the true law has a higher order)."""
    law = pre["laws"].get("c")
    if law is None:
        c = pre["coefficients"].get("c")
        if c is None:
            return None
        law = [c]
    law = list(law)
    if any(v != 0 for v in law[order + 1:]):
        return None
    return (law + [0.0] * (order + 1))[: order + 1]


def comparison_rows(summary: dict, truth: dict) -> list:
    """Estimates of a campaign's results beside their true values.

    Parameters
    ----------
    summary : dict
        The content of ``results.json`` (:meth:`CampaignResult.summary`).
    truth : dict
        As returned by :func:`campaign_truth`.

    Returns
    -------
    list of dict
        One row per estimate that the results give and the truth defines: ``parameter``
        (a label common to all campaigns, e.g. ``"groups.k3"``, ``"damping_law.c1"``,
        ``"records.c_pooled"``, ``"models.omega1"``; each key of ``results.json`` with a
        ``*_stderr`` sibling, and its ``*_ci95`` when given), ``where`` (group, preload or record),
        ``estimate``, ``stderr``, ``ci95`` (``[low, high]`` or None), ``truth``, ``z`` and
        ``covered`` (the interval contains the truth; without an interval ``|z| <= 1.96``).
        Missing estimates (a failed group) give rows with ``estimate`` None.
    """
    pre = {str(p["preload"]): p for p in truth["preloads"]}
    recs = {r["index"]: r for r in truth["records"]}
    rows = []

    def shared(p, name):
        t = pre.get(str(p))
        if t is None or name not in t["coefficients"]:
            return None
        return t["coefficients"][name]

    def add_omega1_k3(section, entry, where, omega1_key="omega1", k3_key="k3"):
        w2 = shared(entry.get("preload"), "omega1^2")
        if w2 is not None and omega1_key in entry:
            rows.append(_row(f"{section}.omega1", where, entry.get(omega1_key), entry.get(f"{omega1_key}_stderr"),
                             float(np.sqrt(w2)), _interval(entry.get(f"{omega1_key}_ci95"))))
        k3 = shared(entry.get("preload"), "k3")
        if k3 is not None and entry.get(k3_key) is not None:
            rows.append(_row(f"{section}.k3", where, entry.get(k3_key), entry.get(f"{k3_key}_stderr"), k3,
                             _interval(entry.get(f"{k3_key}_ci95"))))

    def add_law(section, where, preload, coefs, stderr, ci):
        t = pre.get(str(preload))
        if t is None or coefs is None:
            return
        true = _law_truth(t, len(coefs) - 1)
        if true is None:
            return
        stderr = stderr or [None] * len(coefs)
        for k, (v, s) in enumerate(zip(coefs, stderr)):
            rows.append(_row(f"{section}.c{k}", where, v, s, true[k], _interval(ci, k)))

    for g in summary.get("groups", []):
        add_omega1_k3("groups", g, f"preload={g.get('preload')}, force_level={g.get('force_level')}")
    for law in summary.get("damping_law", []):
        add_law("damping_law", f"preload={law.get('preload')}", law.get("preload"), law.get("coefficients"),
                law.get("stderr"), law.get("coefficients_ci95", law.get("ci95")))
    for m in summary.get("models", []) or []:
        where = f"preload={m.get('preload')}"
        add_omega1_k3("models", m, where)
        add_law("models.damping", where, m.get("preload"), m.get("damping_coefficients"), m.get("damping_stderr"),
                m.get("damping_ci95"))
    for r in summary.get("records", []):
        t = recs.get(r.get("index"))
        if t is None or r.get("status") != "ok":
            continue
        where = f"record {r['index']}"
        w2 = t["coefficients"].get("omega1^2")
        if w2 is not None and "omega1_stderr" in r:
            rows.append(_row("records.omega1", where, r.get("omega1"), r.get("omega1_stderr"), float(np.sqrt(w2)),
                             _interval(r.get("omega1_ci95"))))
        c = t["coefficients"].get("c")
        if c is not None and "c_pooled" in r:
            rows.append(_row("records.c_pooled", where, r.get("c_pooled"), r.get("c_pooled_stderr"), c,
                             _interval(r.get("c_pooled_ci95"))))
        if c is not None and "c_stderr" in r:
            rows.append(_row("records.c", where, r.get("c"), r.get("c_stderr"), c, _interval(r.get("c_ci95"))))
        coefs, errs = r.get("coefficients") or {}, r.get("stderr") or {}
        cis = r.get("coefficients_ci95") or r.get("ci95") or {}
        for name, v in coefs.items():
            if name in t["coefficients"]:
                rows.append(_row(f"records.coefficients.{name}", where, v, errs.get(name), t["coefficients"][name],
                                 _interval(cis.get(name) if isinstance(cis, dict) else None)))
    return rows


# ----------------------------------------------------------------------------------------------------------
# one campaign

#: Scratch folders of the campaigns in the temporary directory: ``jointid-study-<pid>-<random>``.
SCRATCH_PREFIX = "jointid-study-"


def remove_stale_scratch(folder=None) -> list:
    """Remove the campaign scratch folders of processes that are gone (a worker killed mid-campaign).

    Only folders named ``jointid-study-<pid>-...`` whose process no longer runs on this machine
    are removed (a folder of a running study, here or in another worker, is left alone).

    Returns
    -------
    list of Path
        The folders removed.
    """
    import shutil

    from ..io.outputset import pid_alive

    folder = Path(folder or tempfile.gettempdir())
    removed = []
    try:
        candidates = list(folder.glob(f"{SCRATCH_PREFIX}*-*"))
    except OSError:
        return removed
    for p in candidates:
        pid = p.name[len(SCRATCH_PREFIX):].split("-", 1)[0]
        if not pid.isdigit() or not p.is_dir() or p.is_symlink() or pid_alive(int(pid)):
            continue
        shutil.rmtree(p, ignore_errors=True)
        removed.append(p)
    return removed



def run_campaign(plan: StudyPlan, index: int) -> dict:
    """Simulate, identify and compare campaign ``index`` of a plan; never raises for a bad campaign.

    Returns
    -------
    dict
        The campaign's line of ``campaigns.jsonl`` (JSON-safe): ``index``, ``seed``, ``plan``
        (fingerprint), ``grid_point``, ``drawn`` (the values drawn), ``status`` (``"ok"`` or
        ``"failed"``), ``error``, ``n_records``, ``n_failed`` and ``rows`` (:func:`comparison_rows`).
    """
    from ..io.results import to_jsonable
    from .synthesis import load_simulation_config, simulate_campaign
    from .workflow import identify_campaign

    line = {"index": int(index), "seed": plan.campaign_seed(index), "plan": plan.fingerprint, "grid_point": None,
            "drawn": None, "status": "failed", "error": None, "n_records": 0, "n_failed": 0, "rows": []}
    try:
        tables, drawn, point = plan.draw(index)
        line.update(grid_point=point, drawn=to_jsonable(drawn))
        config = load_simulation_config(tables, source=f"{plan.source} campaign {index}")
        truth = campaign_truth(config)
        settings = replace(plan.settings, jobs=1, scheduler=None, progress=False)
        remove_stale_scratch()
        with tempfile.TemporaryDirectory(prefix=f"{SCRATCH_PREFIX}{os.getpid()}-") as tmp:
            simulate_campaign(config, Path(tmp) / "campaign")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", JointidWarning)
                result = identify_campaign(Path(tmp) / "campaign", settings)
            summary = to_jsonable(result.summary())
        line.update(status="ok", n_records=summary["n_records"], n_failed=summary["n_failed"],
                    rows=to_jsonable(comparison_rows(summary, truth)))
    except JointidError as exc:
        line["error"] = f"campaign {index}: {exc}"
    except Exception as exc:  # noqa: BLE001 - one campaign must never lose the study
        line["error"] = f"campaign {index}: unexpected {type(exc).__name__}: {exc}"
    return line


# ----------------------------------------------------------------------------------------------------------
# statistics


def _wilson(k, n, z=1.96):
    if n == 0:
        return (None, None)
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (float(mid - half), float(mid + half))


def study_statistics(lines) -> list:
    """Bias, RMSE, std(z) and 95 % coverage per grid point and parameter.

    Parameters
    ----------
    lines : iterable of dict
        Campaign lines (:func:`run_campaign`), in any order (they are sorted by index, so the
        statistics do not depend on the order in which campaigns finished).

    Returns
    -------
    list of dict
        ``grid_point``, ``parameter``, ``n`` (rows), ``n_missing`` (no estimate), ``bias``
        (mean of estimate - truth), ``rmse``, ``rel_bias`` and ``rel_rmse`` (relative to
        ``|truth|``, rows with a non-zero truth), ``n_z``, ``mean_z``, ``std_z``, ``coverage``
        (fraction of rows whose interval holds the truth) with its Wilson 95 % interval
        (``coverage_low``, ``coverage_high``).
    """
    groups = {}
    for line in sorted(lines, key=lambda l: l["index"]):
        for r in line.get("rows") or []:
            groups.setdefault((line["grid_point"], r["parameter"]), []).append(r)
    out = []
    for (point, name) in sorted(groups, key=lambda k: (k[0], k[1])):
        rows = groups[(point, name)]
        ok = [r for r in rows if r["estimate"] is not None]
        err = np.array([r["estimate"] - r["truth"] for r in ok], float)
        rel = np.array([(r["estimate"] - r["truth"]) / abs(r["truth"]) for r in ok if r["truth"] != 0], float)
        z = np.array([r["z"] for r in ok if r["z"] is not None], float)
        cov = [r["covered"] for r in ok if r["covered"] is not None]
        low, high = _wilson(sum(cov), len(cov))
        out.append({
            "grid_point": point,
            "parameter": name,
            "n": len(rows),
            "n_missing": len(rows) - len(ok),
            "bias": float(err.mean()) if err.size else None,
            "rmse": float(np.sqrt(np.mean(err**2))) if err.size else None,
            "rel_bias": float(rel.mean()) if rel.size else None,
            "rel_rmse": float(np.sqrt(np.mean(rel**2))) if rel.size else None,
            "n_z": int(z.size),
            "mean_z": float(z.mean()) if z.size else None,
            "std_z": float(z.std(ddof=1)) if z.size > 1 else None,
            "coverage": float(np.mean(cov)) if cov else None,
            "coverage_low": low,
            "coverage_high": high,
        })
    return out


# ----------------------------------------------------------------------------------------------------------
# the study


@dataclass(frozen=True)
class StudyResult:
    """A finished (or resumed and finished) study.

    Attributes
    ----------
    name : str
    plan : StudyPlan
    campaigns : tuple of dict
        The campaign lines, by index.
    statistics : tuple of dict
        :func:`study_statistics` of the campaigns.
    n_run : int
        Campaigns run by this call (the others were in the results file already).
    """

    name: str
    plan: StudyPlan = field(repr=False)
    campaigns: tuple = field(repr=False)
    statistics: tuple = field(repr=False)
    n_run: int = field(default=0, compare=False)

    @property
    def failed(self):
        return [c for c in self.campaigns if c["status"] != "ok"]

    def summary(self) -> dict:
        """``study.json``: the plan, the grid points, the counts and the statistics (JSON-safe)."""
        from ..io.results import to_jsonable

        return to_jsonable({
            "study": self.name,
            "plan_fingerprint": self.plan.fingerprint,
            "plan": self.plan.mapping(),
            "grid_points": self.plan.points,
            "n_campaigns": len(self.campaigns),
            "n_failed": len(self.failed),
            "errors": [c["error"] for c in self.failed[:20]],
            "statistics": list(self.statistics),
        })

    def report(self) -> str:
        from ..report.study_plots import statistics_table

        head = (f"study {self.name!r}: {len(self.campaigns)} campaigns ({len(self.failed)} failed), "
                f"plan {self.plan.fingerprint}")
        lines = [head]
        points = self.plan.points
        for k, point in enumerate(points):
            if len(points) > 1:
                lines.append(f"\ngrid point {k}: " + ", ".join(f"{p} = {v}" for p, v in point.items()))
            lines.append(statistics_table([s for s in self.statistics if s["grid_point"] == k]))
        for c in self.failed[:10]:
            lines.append(f"  failed: {c['error']}")
        if getattr(self, "provenance", None):
            from ..report.provenance_text import provenance_line

            lines.append(provenance_line(self.provenance))
        return "\n".join(lines)

    def _repr_html_(self):
        return "<pre>" + html.escape(self.report()) + "</pre>"

    def plot(self, grid_point=0, ax=None):
        """std(z) and 95 % coverage per parameter (see :func:`jointid.report.study_plots.plot_calibration`)."""
        from ..report.study_plots import plot_calibration

        return plot_calibration([s for s in self.statistics if s["grid_point"] == grid_point], ax=ax)


def _torn_tail(data: bytes) -> bytes:
    """The bytes after the last newline (a line cut short by a killed run), or ``b""``."""
    return data[data.rfind(b"\n") + 1:]


def _tail_plan(tail: bytes):
    """The plan fingerprint written at the start of a line cut short, if it got that far."""
    import re

    m = re.search(rb'"plan": "([0-9a-f]{16})"', tail)
    return m.group(1).decode() if m else None


def _no_constant(name):
    raise ValueError(f"{name} is not a number a campaign line holds (lines are written without NaN or infinities)")


def _line_index(line, where) -> int:
    if not isinstance(line, dict):
        raise ManifestError(f"{where}: not a campaign line: a JSON object expected, got {type(line).__name__}")
    if "index" not in line:
        raise ManifestError(f"{where}: not a campaign line: no 'index'")
    index = line["index"]
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < MAX_CAMPAIGNS:
        raise ManifestError(f"{where}: not a campaign line: index must be an integer from 0 to {MAX_CAMPAIGNS - 1}, "
                            f"got {index!r}")
    return index


_LINE_KEYS = ("index", "seed", "plan", "grid_point", "status", "error", "rows")
_ROW_KEYS = ("parameter", "estimate", "stderr", "truth", "z", "covered")


def _check_campaign_line(line, where, plan=None) -> None:
    """The keys and values of a campaign line that a resumed study uses (see :func:`run_campaign`)."""
    for k in _LINE_KEYS:
        if k not in line:
            raise ManifestError(f"{where}: not a campaign line: no {k!r}")
    index = line["index"]

    def bad(key, expected):
        shown = repr(line.get(key))
        raise ManifestError(f"{where}: campaign {index}: {key} must be {expected}, got "
                            f"{shown if len(shown) <= 80 else shown[:77] + '...'}")

    def count(v):
        return isinstance(v, int) and not isinstance(v, bool) and v >= 0

    if not count(line["seed"]) or (plan is not None and line["seed"] != plan.campaign_seed(index)):
        bad("seed", "the campaign's seed from the plan" if plan is not None else "a non-negative integer")
    n_points = len(plan.points) if plan is not None else None
    gp = line["grid_point"]
    if not (count(gp) and (n_points is None or gp == index % n_points)) and not (gp is None and line["status"] != "ok"):
        bad("grid_point", f"index % {n_points} = {index % n_points}" if n_points else "a non-negative integer")
    if line["status"] not in ("ok", "failed"):
        bad("status", "'ok' or 'failed'")
    if not (line["error"] is None or isinstance(line["error"], str)):
        bad("error", "a string or null")
    for k in ("n_records", "n_failed"):
        if k in line and not count(line[k]):
            bad(k, "a non-negative integer")
    rows = line["rows"]
    if not isinstance(rows, list):
        bad("rows", "a list of comparison rows")
    for j, r in enumerate(rows):
        at = f"{where}: campaign {index}: rows[{j}]"
        if not isinstance(r, dict):
            raise ManifestError(f"{at}: a comparison row (JSON object) expected, got {r!r}"[:300])
        for k in _ROW_KEYS:
            if k not in r:
                raise ManifestError(f"{at}: no {k!r}")
        if not isinstance(r["parameter"], str):
            raise ManifestError(f"{at}: parameter must be a string, got {r['parameter']!r}")
        if not _finite(r["truth"]) or isinstance(r["truth"], bool):
            raise ManifestError(f"{at}: truth must be a finite number, got {r['truth']!r}")
        for k in ("estimate", "stderr", "z"):
            if r[k] is not None and (isinstance(r[k], bool) or not _finite(r[k])):
                raise ManifestError(f"{at}: {k} must be a finite number or null, got {r[k]!r}"[:300])
        if r["covered"] is not None and not isinstance(r["covered"], bool):
            raise ManifestError(f"{at}: covered must be true, false or null, got {r['covered']!r}"[:300])
        ci = r.get("ci95")
        if ci is not None and not (isinstance(ci, list) and len(ci) == 2 and all(
                _finite(x) and not isinstance(x, bool) for x in ci)):
            raise ManifestError(f"{at}: ci95 must be a pair of finite numbers or null, got {ci!r}"[:300])


def read_campaign_lines(path, plan: StudyPlan | None = None) -> dict:
    """The campaign lines of a results file, by index; the file is only read, never changed.

    A last line cut short (an interrupted run) is left out; :func:`run_study` removes it
    from the file when it resumes the same plan.

    Raises
    ------
    jointid.errors.ManifestError
        A line that is not a campaign line (other than the last), or lines of another plan
        (also a last line cut short that shows another plan).
    """
    path = Path(path)
    if not path.is_file():
        return {}
    data = path.read_bytes()
    tail = _torn_tail(data)
    out, first = {}, {}
    try:
        text = data[:len(data) - len(tail)].decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ManifestError(f"{path}: not a campaigns file of jointid (not UTF-8 text: {exc})") from None
    for n, line_text in enumerate(text.splitlines(), 1):
        if not line_text.strip():
            continue
        try:
            line = json.loads(line_text, parse_constant=_no_constant)
        except (ValueError, RecursionError) as exc:
            raise ManifestError(f"{path} [line {n}]: not a campaign line: {exc}") from None
        index = _line_index(line, f"{path} [line {n}]")
        if plan is not None and line.get("plan") != plan.fingerprint:
            raise ManifestError(
                f"{path} [line {n}]: campaign {index} was made by another plan (fingerprint {line.get('plan')}, "
                f"this plan {plan.fingerprint}); write the study to another folder or remove the file")
        _check_campaign_line(line, f"{path} [line {n}]", plan)
        if index in out and out[index] != line:  # the same line twice is harmless; two outcomes of one campaign are not
            raise ManifestError(f"{path} [line {n}]: campaign {index} is already on line {first[index]} with another "
                                f"outcome: the file mixes runs; write the study to another folder")
        first.setdefault(index, n)
        out[index] = line
    if plan is not None and tail.strip():
        other = _tail_plan(tail)
        if other is not None and other != plan.fingerprint:
            raise ManifestError(
                f"{path}: its last line (cut short) was made by another plan (fingerprint {other}, this plan "
                f"{plan.fingerprint}); write the study to another folder or remove the file")
    return out


STUDY_FINAL_FILES = ("study.json", "statistics.csv", "report.html")


class StudyInterrupted(KeyboardInterrupt):
    """A study stopped by Ctrl-C; its message says what the output folder holds and how to resume."""


def _final_state(out: Path) -> str:
    """What the final files of a study folder describe (from its marker), in words."""
    from ..io.outputset import read_marker

    marker = read_marker(out) or {}
    n = marker.get("campaigns")
    if n and n.isdigit():
        return (f"{', '.join(f for f in STUDY_FINAL_FILES if (out / f).is_file())} are those of the last complete run "
                f"({n} campaigns)")
    if (out / "study.json").is_file():
        return "study.json and the other final files are those of an earlier run"
    return "no study.json is written yet"


def check_study_folder(out, plan: StudyPlan | None = None) -> dict | None:
    """Refuse a study output folder before any work; returns its marker (None for a new or older folder).

    A study writes into its folder (``campaigns.jsonl`` grows as campaigns finish and a study
    is resumed there), so the folder must be new, empty, or a study folder: one marked as
    such by jointid (of the same plan), or one of an earlier version that holds only the
    files of a study.

    Raises
    ------
    jointid.errors.OutputError
    """
    from ..errors import OutputError
    from ..io.outputset import MARKER, check_output_folder, read_marker

    out = Path(out)
    plan_file = Path(plan.source) if plan is not None and Path(plan.source).is_file() else None
    check_output_folder(out, "study", (plan_file,), replace=False)
    if not out.is_dir():
        return None
    names = {p.name for p in out.iterdir()}
    if not names:
        return None
    marker = read_marker(out)
    if marker is None:
        own = {RESULTS_FILE, *STUDY_FINAL_FILES}
        if RESULTS_FILE in names and {n for n in names if not n.startswith(".")} <= own:
            return None  # a study folder of an earlier version
        raise OutputError(f"{out}: exists and holds files that are not a jointid study (no {MARKER} marker); a "
                          f"study writes into its folder, so give a new or empty folder, or the folder of the same study")
    if marker["kind"] != "study":
        raise OutputError(f"{out}: holds a jointid {marker['kind']} output set; a study never replaces or mixes "
                          f"with another kind, so give another folder")
    if plan is not None and marker.get("plan") not in (None, plan.fingerprint):
        raise ManifestError(f"{out}: holds a study of another plan (fingerprint {marker.get('plan')}, this plan "
                            f"{plan.fingerprint}); write the study to another folder")
    return marker


def _check_code_versions(path, done: dict, allow: bool) -> None:
    """Refuse to resume campaigns made by other jointid code (lines of an earlier version, without
    a ``code`` entry, are not checked)."""
    from .provenance import code_fingerprint

    here = code_fingerprint()
    other = sorted({str(line.get("code")) for line in done.values() if line.get("code") not in (None, here)})
    if other and not allow:
        n = sum(1 for line in done.values() if line.get("code") not in (None, here))
        raise ManifestError(f"{path}: {n} campaign(s) were made by other jointid code (code fingerprint "
                            f"{', '.join(other)}; this jointid is {here}); resuming would mix versions in one study: "
                            f"write to another folder, or resume with --allow-version-mix")


def _move_ready(out: Path, ready: Path) -> None:
    """Put a committed final set in place: its files, then its marker (last: it says which set is
    in place); a final file of an earlier run that the set does not have (``report.html`` after
    ``--no-report``) describes other campaigns and is removed."""
    from ..io.outputset import MARKER, read_marker

    marker = read_marker(ready)
    for p in sorted(ready.iterdir()):
        if p.name != MARKER:
            os.replace(p, out / p.name)
    if marker is not None:
        for name in STUDY_FINAL_FILES:
            if name not in (marker["files"] or ()) and (out / name).is_file():
                (out / name).unlink()
        os.replace(ready / MARKER, out / MARKER)
    ready.rmdir()


def _recover_final(out: Path) -> None:
    """Finish the final set that a killed run had committed; remove the uncommitted ones of dead runs."""
    import shutil

    from ..io.outputset import pid_alive

    if not out.is_dir():
        return
    for p in sorted(out.glob(".final.*.ready")):
        _move_ready(out, p)
    for p in out.glob(".final.*-*.tmp"):
        pid = p.name[len(".final."):].split("-", 1)[0]
        if pid.isdigit() and not pid_alive(int(pid)):
            shutil.rmtree(p, ignore_errors=True)


def _write_final_set(out: Path, result, run_id: str, report: bool) -> None:
    """Write ``study.json``, ``statistics.csv`` and ``report.html`` as one set.

    The files and a marker (run id, plan, number of campaigns they describe, the files) are
    written into ``.final.<pid>-<run id>.tmp``; renaming it to ``.final.<run id>.ready`` is
    the commit, after which the files are moved into place (Ctrl-C held back meanwhile).  A run
    killed before the commit leaves the previous set; one killed after it leaves the ready
    folder, which the next run on the folder moves into place before anything else.
    """
    import shutil

    from ..io.outputset import MARKER, deferred_interrupt, marker_text
    from ..io.results import atomic_write, write_csv, write_json

    tmp = out / f".final.{os.getpid()}-{run_id}.tmp"
    tmp.mkdir()
    try:
        summary = result.summary()
        summary["run_id"] = run_id
        if getattr(result, "provenance", None):  # who ran it, where, how long (not part of the results)
            summary["provenance"] = result.provenance
        write_json(tmp / "study.json", summary)
        write_csv(tmp / "statistics.csv", list(result.statistics),
                  columns=list(result.statistics[0]) if result.statistics else ["grid_point", "parameter"])
        if report:
            from ..report.study_plots import write_study_report

            write_study_report(result, tmp / "report.html")
        files = sorted(p.name for p in tmp.iterdir())
        atomic_write(tmp / MARKER, marker_text(run_id, "study", [RESULTS_FILE] + files, plan=result.plan.fingerprint,
                                               campaigns=len(result.campaigns)))
        ready = out / f".final.{run_id}.ready"
        with deferred_interrupt():
            os.rename(tmp, ready)
            _move_ready(out, ready)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def run_study(plan, out_dir, *, jobs=1, scheduler=None, client=None, progress=False, report=True,
              allow_version_mix=False) -> StudyResult:
    """Run (or resume) a study and write its results.

    Parameters
    ----------
    plan : StudyPlan, dict or path
        The plan (a :class:`StudyPlan`, its tables, or a TOML file).
    out_dir : path
        Output folder: ``campaigns.jsonl`` (one line per campaign, appended as campaigns
        finish and sorted by index at the end), ``study.json``, ``statistics.csv`` and
        ``report.html``.  Campaigns already in ``campaigns.jsonl`` are not run again.  The
        three final files are written as one set once every campaign is done
        (:func:`_write_final_set`); the folder's marker says how many campaigns they describe.
    jobs : int, default 1
        ``1``: in this process; ``N``: a local dask cluster of ``N`` workers; ``0``: one per core.
    scheduler : str, optional
        Address of an existing dask scheduler (overrides ``jobs``).
    client : distributed.Client, optional
        An open client (overrides ``jobs`` and ``scheduler``).
    progress : bool
        Show the progress.
    report : bool
        Write ``report.html`` (figures take a few seconds).
    allow_version_mix : bool
        Resume campaigns made by other jointid code (another code fingerprint,
        :func:`jointid.app.provenance.code_fingerprint`); refused by default.

    Returns
    -------
    StudyResult

    Raises
    ------
    jointid.errors.OutputError
        ``out_dir`` is not a study folder (see :func:`check_study_folder`).
    jointid.errors.ClusterLostError
        The cluster was lost: the campaigns done are in ``campaigns.jsonl`` and the final files
        are left as they were; running the same study again resumes it.
    StudyInterrupted
        Ctrl-C (a KeyboardInterrupt whose message says what the folder holds).
    """
    from ..errors import ClusterLostError
    from ..io.outputset import MARKER, marker_text, new_run_id
    from ..io.results import atomic_write
    from .parallel import map_tasks
    from .provenance import RunClock, attach_provenance, code_fingerprint

    clock = RunClock()
    code = code_fingerprint()
    if client is None and scheduler is None:
        check_study_jobs(jobs)
    if not isinstance(plan, StudyPlan):
        plan = StudyPlan.from_mapping(plan) if isinstance(plan, dict) else load_study_plan(plan)
    out = Path(out_dir)
    marker = check_study_folder(out, plan)
    if scheduler is not None and client is None:  # a bad address or no scheduler there: before the folder is made
        from .parallel import check_scheduler

        check_scheduler(scheduler)
    _recover_final(out)
    path = out / RESULTS_FILE
    done = read_campaign_lines(path, plan)  # refuses lines of another plan; changes nothing
    tail = _torn_tail(path.read_bytes()) if path.is_file() else b""
    if tail.strip() and marker is None and not done and _tail_plan(tail) is None:
        raise ManifestError(f"{path}: holds only a line cut short before it names its plan, in a folder without a "
                            f"study marker: which plan made it cannot be told; remove the file or write the study to "
                            f"another folder")
    _check_code_versions(path, done, allow_version_mix)
    created = [p for p in (out, out / MARKER, path) if not p.exists()]
    out.mkdir(parents=True, exist_ok=True)
    if marker is None:
        atomic_write(out / MARKER, marker_text(new_run_id(), "study", plan=plan.fingerprint, campaigns="none"))
    if path.is_file() and _torn_tail(path.read_bytes()):  # a line cut short by a killed run of this plan
        data = path.read_bytes()
        atomic_write(path, data[:len(data) - len(_torn_tail(data))])
    todo = [i for i in range(plan.n_campaigns) if i not in done]
    n_before = len(done)

    def saved():
        n_plan = sum(1 for i in range(plan.n_campaigns) if i in done)
        return f"{n_plan} of {plan.n_campaigns} campaigns are saved in {path}"

    try:
        with open(path, "a", encoding="utf-8") as fh:

            def append(_, line):
                line["code"] = code  # the jointid code of the run that made the line (a resumed study checks it)
                fh.write(json.dumps(line, allow_nan=False) + "\n")
                fh.flush()
                os.fsync(fh.fileno())
                done[line["index"]] = line

            def lost(i, message):  # failed in this run, not written: a resumed study tries it again
                index = todo[i]
                return {"index": index, "seed": plan.campaign_seed(index), "plan": plan.fingerprint,
                        "grid_point": index % len(plan.points), "drawn": None, "status": "failed",
                        "error": f"campaign {index}: lost on the workers: {message}", "n_records": 0, "n_failed": 0,
                        "rows": []}

            new = map_tasks(run_campaign, [(plan, i) for i in todo], jobs=jobs, scheduler=scheduler, client=client,
                            progress=progress, desc="campaigns", on_result=append, on_lost=lost,
                            cleanup=remove_stale_scratch)
    except BaseException as exc:
        cleaned = bool(len(done) == n_before == 0 and created)  # nothing run in a new folder: leave no trace of it
        for p in reversed(created if cleaned else []):
            if p.is_dir():
                with contextlib.suppress(OSError):
                    p.rmdir()
            elif p.exists():
                p.unlink()
        state = ("no campaign was run and nothing was written" if cleaned
                 else f"{saved()} and {_final_state(out)}; run the same command again to resume")
        if isinstance(exc, ClusterLostError):
            raise ClusterLostError(f"{str(exc).split(' after ')[0]}; {state}", exc.done, exc.total) from None
        if isinstance(exc, KeyboardInterrupt):
            raise StudyInterrupted(state) from None
        raise
    finally:
        remove_stale_scratch()  # scratch folders of workers killed in this run (also run on each worker at the end)
    lines = [done[i] for i in sorted(done)]
    atomic_write(path, "".join(json.dumps(line, allow_nan=False) + "\n" for line in lines))
    lost_lines = {line["index"]: line for line in new if line["index"] not in done}
    current = tuple(done.get(i) or lost_lines[i] for i in range(plan.n_campaigns))
    result = StudyResult(plan.name, plan, current, tuple(study_statistics(current)), n_run=len(todo))
    attach_provenance(result, clock, plan_fingerprint=plan.fingerprint)
    run_id = new_run_id()
    try:
        _write_final_set(out, result, run_id, report)
    except KeyboardInterrupt:
        from ..io.outputset import read_marker

        if (read_marker(out) or {}).get("run_id") == run_id:  # Ctrl-C held back until the set was in place
            raise StudyInterrupted(f"the study was complete: all {plan.n_campaigns} campaigns are saved in {path} and "
                                   f"the final files written") from None
        raise StudyInterrupted(f"all {plan.n_campaigns} campaigns are saved in {path} and {_final_state(out)}; "
                               f"run the same command again to write the final files") from None
    return result
