"""Write simulated stepped-sine campaigns of the single-mode model from a TOML configuration.

Configuration (all keys optional except the model's ``omega1``)::

    [campaign]
    name = "seed numerical example"

    [[model]]                       # one table per preload configuration
    preload = "sim"                 # grouping label written to every record
    terms = "q + -q^3 + q'"         # restoring-force terms
    omega1 = 170.0                  # rad/s (coefficient of q is omega1^2)
    coefficients = { k3 = 5e6 }     # other coefficients by name
    amplitude_laws = { c = [0.08, 70.0, 1e4] }   # c(q_max) = c0 + c1 q_max + c2 q_max^2

    [excitation]
    force_levels = [1.0]            # amplitudes F of Q(t) = F sin(omega t)
    omega_start = 160.0             # rad/s ...
    omega_stop = 180.0
    n_frequencies = 41              # ... or frequencies_hz = [...]

    [acquisition]
    fs = 5000.0                     # Hz
    periods = 20.0                  # record length in excitation periods (may be fractional)
    t0 = 0.0                        # start time of every record [s]
    noise = 0.0                     # white noise, fraction of each channel's RMS
    seed = 0                        # noise seed (the same seed gives the same campaign)
    write_frequency = true          # write frequency_hz into the manifest
    n_harmonics = 9                 # harmonics of the harmonic-balance steady state

The steady states are computed by harmonic balance (with the amplitude closure solved
exactly) and sampled analytically, so a record is the exact periodic response plus noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConvergenceError, ManifestError, unknown_key_message
from ..identify.terms import library
from ..io.campaign import read_toml, write_campaign, write_csv_record
from ..simulate.model import SingleModeModel

__all__ = ["SimulationConfig", "load_simulation_config", "simulate_campaign", "model_from_mapping"]


# ----------------------------------------------------------------------------------------------------------
# what a configuration may hold (also the tables of a study plan, jointid.app.study)

# the keys of each simulation table (a study plan's [vary] and [grid] paths address them too)
_TABLES = {
    "campaign": ("name",),
    "model": ("preload", "terms", "omega1", "k3", "coefficients", "amplitude_laws"),
    "excitation": ("force_levels", "omega_start", "omega_stop", "n_frequencies", "frequencies_hz"),
    "acquisition": ("fs", "periods", "t0", "noise", "seed", "write_frequency", "n_harmonics"),
}

MAX_SEED = 2**63 - 1
MAX_PRELOADS = 20  # [[model]] tables of a campaign
MAX_LEVELS = 50  # force levels (also the largest `size` of a draw)
MAX_FREQUENCIES = 1_000
MAX_LAW_ORDER = 10
# a campaign that one worker simulates and identifies (stated in docs/formats.md, "Study plan"); a
# simulation configuration and every campaign a study plan can draw are held to them
MAX_CAMPAIGN_RECORDS = 5_000  # preloads x force levels x frequencies
MAX_RECORD_SAMPLES = 2_000_000  # fs x periods / lowest frequency
_INF = float("inf")

# what a key of the simulation tables holds: ("number", low, high, low excluded), ("int", low, high),
# ("bool",), ("str",), ("label",) (a string or a number), ("list", element, min length, max length),
# ("table", value) (a table of name -> value)
_POSITIVE = ("number", 0.0, 1e7, True)
_SPECS = {
    ("campaign", "name"): ("str",),
    ("model", "preload"): ("label",),
    ("model", "terms"): ("str",),
    ("model", "omega1"): _POSITIVE,
    ("model", "k3"): ("number", -_INF, _INF, False),
    ("model", "coefficients"): ("table", ("number", -_INF, _INF, False)),
    ("model", "amplitude_laws"): ("table", ("list", ("number", -_INF, _INF, False), 1, MAX_LAW_ORDER + 1)),
    ("excitation", "force_levels"): ("list", ("number", 0.0, 1e9, True), 1, MAX_LEVELS),
    ("excitation", "omega_start"): _POSITIVE,
    ("excitation", "omega_stop"): _POSITIVE,
    ("excitation", "n_frequencies"): ("int", 1, MAX_FREQUENCIES),
    ("excitation", "frequencies_hz"): ("list", ("number", 0.0, 1e6, True), 1, MAX_FREQUENCIES),
    ("acquisition", "fs"): ("number", 0.0, 1e6, True),
    ("acquisition", "periods"): ("number", 2.0, 1e5, False),
    ("acquisition", "t0"): ("number", -1e9, 1e9, False),
    ("acquisition", "noise"): ("number", 0.0, 1e3, False),
    ("acquisition", "seed"): ("int", 0, MAX_SEED),
    ("acquisition", "write_frequency"): ("bool",),
    ("acquisition", "n_harmonics"): ("int", 1, 50),
}


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _describe(spec) -> str:
    kind = spec[0]
    if kind == "number":
        lo, hi, open_lo = spec[1:]
        low = "" if lo == -_INF else (f" > {lo:g}" if open_lo else f" >= {lo:g}")
        high = "" if hi == _INF else f" <= {hi:g}"
        return "a finite number" + (f"{low}{' and' if low and high else ''}{high}" if low or high else "")
    if kind == "int":
        return f"an integer from {spec[1]} to {spec[2]}"
    if kind == "list":
        return f"a list of {spec[2]} to {spec[3]} values, each {_describe(spec[1])}"
    if kind == "table":
        return f"a table whose values are each {_describe(spec[1])}"
    return {"bool": "true or false", "str": "a string", "label": "a string or a number"}[kind]


def _value_ok(spec, v) -> bool:
    kind = spec[0]
    if kind == "number":
        lo, hi, open_lo = spec[1:]
        return _is_number(v) and math.isfinite(v) and (lo < v if open_lo else lo <= v) and v <= hi
    if kind == "int":
        return isinstance(v, int) and not isinstance(v, bool) and spec[1] <= v <= spec[2]
    if kind == "bool":
        return isinstance(v, bool)
    if kind == "str":
        return isinstance(v, str)
    if kind == "label":
        return isinstance(v, str) or (_is_number(v) and math.isfinite(v))
    if kind == "list":
        return isinstance(v, list) and spec[2] <= len(v) <= spec[3] and all(_value_ok(spec[1], x) for x in v)
    if kind == "table":
        return isinstance(v, dict) and all(isinstance(k, str) and _value_ok(spec[1], x) for k, x in v.items())
    return False  # pragma: no cover


def _check_value(spec, v, where):
    if spec[0] == "table" and isinstance(v, dict):  # name the entry at fault
        for k, x in v.items():
            _check_value(spec[1], x, f"{where}.{k}")
    if not _value_ok(spec, v):
        extra = ""
        if spec == _SPECS[("model", "amplitude_laws")][1] and isinstance(v, str):
            extra = " (a simulated law is a polynomial [c0, c1, ...] in the amplitude; the power law is not simulated)"
        shown = repr(v) if len(repr(v)) <= 80 else repr(v)[:77] + "..."
        raise ManifestError(f"{where}: expected {_describe(spec)}, got {shown}{extra}")


def _tables_of(d, name, source):
    """The tables under ``name`` (``[[model]]`` may be several), checked to be tables."""
    node = d.get(name)
    if node is None:
        return []
    items = node if (name == "model" and isinstance(node, list)) else [node]
    if name == "model" and isinstance(node, list) and not 1 <= len(node) <= MAX_PRELOADS:
        raise ManifestError(f"{source}: [[model]] needs 1 to {MAX_PRELOADS} tables, got {len(node)}")
    for item in items:
        if not isinstance(item, dict):
            raise ManifestError(f"{source}: [{name}] must be a table, got {type(node).__name__} {node!r}"[:300])
    return items


def check_simulation_tables(d, source):
    """Known keys (with the nearest valid one as a hint), types and bounds of the simulation tables."""
    for name, keys in _TABLES.items():
        for table in _tables_of(d, name, source):
            for k, v in table.items():
                if k not in keys:
                    raise ManifestError(f"{source}: [{name}] {unknown_key_message(k, keys)}")
                _check_value(_SPECS[(name, k)], v, f"{source}: [{name}] {k}")


def check_campaign_size(n_models, n_levels, n_freq, fs, periods, f_low, source) -> None:
    """Records per campaign and samples per record stay within what one worker simulates and identifies.

    ``f_low`` is the lowest excitation frequency [Hz] (``inf`` when not known); a ManifestError otherwise.
    """
    n_records = n_models * n_levels * n_freq
    if n_records > MAX_CAMPAIGN_RECORDS:
        raise ManifestError(f"{source}: a campaign can hold {n_models} preload(s) x {n_levels} force level(s) x "
                            f"{n_freq} frequencies = {n_records} records; at most {MAX_CAMPAIGN_RECORDS} allowed")
    if f_low < _INF and f_low > 0 and fs * periods / f_low > MAX_RECORD_SAMPLES:
        raise ManifestError(f"{source}: a record can hold fs x periods / lowest frequency = {fs:g} x {periods:g} / "
                            f"{f_low:.4g} Hz = {fs * periods / f_low:.3g} samples; at most {MAX_RECORD_SAMPLES:g} "
                            f"allowed (lower [acquisition] fs or periods)")


def _check_preloads(models, source) -> None:
    """Each ``[[model]]`` table has its own preload label (records are grouped by it)."""
    from ..io.campaign import _same_label

    seen = []
    for i, m in enumerate(models, 1):
        p = m.get("preload", "sim")
        for j, q in seen:
            if _same_label(q, p):  # "120", 120 and 120.0 name one group
                what = (f"both have preload {p!r}" if q == p and type(q) is type(p)
                        else f"have preloads {q!r} and {p!r}, one label in the records")
                raise ManifestError(f"{source}: [[model]] tables {j} and {i} {what}: their records would be "
                                    f"mixed into one preload; give each [[model]] its own preload")
        seen.append((i, p))


def model_from_mapping(d: dict, source="config") -> SingleModeModel:
    """Build a :class:`SingleModeModel` from a ``[model]`` table."""
    try:
        lib = library(d.get("terms", "q + -q^3 + q'"))
    except Exception as exc:
        raise ManifestError(f"{source}: [model] terms: {exc}") from exc
    coefs = dict(d.get("coefficients", {}))
    if "omega1" not in d:
        raise ManifestError(f"{source}: [model] needs omega1 (rad/s)")
    coefs["omega1^2"] = float(d["omega1"]) ** 2
    if "k3" in d:
        coefs["k3"] = float(d["k3"])
    values = []
    for t in lib:
        values.append(float(coefs.pop(t.coefficient, coefs.pop(t.name, 0.0))))
    if coefs:
        raise ManifestError(f"{source}: [model] coefficients {sorted(coefs)} match no term of {lib.names}")
    laws = {}
    for k, v in dict(d.get("amplitude_laws", {})).items():
        try:
            lib.index(k)
        except KeyError as exc:
            raise ManifestError(f"{source}: [model] amplitude law for {k!r}, which is no term of {lib.names}") from exc
        laws[k] = tuple(float(x) for x in v)
    return SingleModeModel(lib, tuple(values), laws)


@dataclass(frozen=True)
class SimulationConfig:
    name: str
    models: tuple  # (preload label, SingleModeModel)
    force_levels: tuple
    omegas: np.ndarray
    fs: float
    periods: float
    t0: float
    noise: float
    seed: int
    write_frequency: bool
    n_harmonics: int
    source: str = "config"  # where the configuration came from (named in errors)


def load_simulation_config(path_or_dict, source=None) -> SimulationConfig:
    """Parse a simulation configuration (TOML file or already-parsed dict)."""
    if isinstance(path_or_dict, dict):
        d, source = path_or_dict, source or "config"
    else:
        source = str(path_or_dict)
        d = read_toml(path_or_dict, "simulation configuration")
    for name in d:
        if name not in _TABLES:
            raise ManifestError(f"{source}: {unknown_key_message(name, _TABLES, 'table')}")
    check_simulation_tables(d, source)
    models = d.get("model")
    if models is None:
        raise ManifestError(f"{source}: a [model] table is required")
    if isinstance(models, dict):
        models = [models]
    _check_preloads(models, source)
    ex = d.get("excitation", {})
    if "frequencies_hz" in ex:
        both = [k for k in ("omega_start", "omega_stop", "n_frequencies") if k in ex]
        if both:
            raise ManifestError(f"{source}: [excitation] gives both frequencies_hz and {'/'.join(both)}; keep one: "
                                f"frequencies_hz (the list of frequencies) or omega_start/omega_stop/n_frequencies "
                                f"(an even sweep)")
    parsed = tuple((m.get("preload", "sim"), model_from_mapping(m, source)) for m in models)
    if "frequencies_hz" in ex:
        omegas = 2 * np.pi * np.asarray(ex["frequencies_hz"], float)
    else:
        try:
            omegas = np.linspace(float(ex["omega_start"]), float(ex["omega_stop"]), int(ex.get("n_frequencies", 41)))
        except KeyError as exc:
            raise ManifestError(f"{source}: [excitation] needs frequencies_hz or omega_start/omega_stop") from exc
    if omegas.size == 0 or np.any(omegas <= 0):
        raise ManifestError(f"{source}: excitation frequencies must be positive")
    acq = d.get("acquisition", {})
    levels = tuple(float(f) for f in ex.get("force_levels", [1.0]))
    cfg = SimulationConfig(
        name=str(d.get("campaign", {}).get("name", "simulated campaign")),
        models=parsed,
        force_levels=levels,
        omegas=omegas,
        fs=float(acq.get("fs", 5000.0)),
        periods=float(acq.get("periods", 20.0)),
        t0=float(acq.get("t0", 0.0)),
        noise=float(acq.get("noise", 0.0)),
        seed=int(acq.get("seed", 0)),
        write_frequency=bool(acq.get("write_frequency", True)),
        n_harmonics=int(acq.get("n_harmonics", 9)),
        source=source,
    )
    if cfg.fs <= 2 * omegas.max() / (2 * np.pi):
        raise ManifestError(f"{source}: fs = {cfg.fs} Hz is below twice the highest excitation frequency")
    if cfg.periods < 2:
        raise ManifestError(f"{source}: periods must be at least 2, got {cfg.periods}")
    check_campaign_size(len(parsed), len(levels), int(omegas.size), cfg.fs, cfg.periods,
                        float(omegas.min()) / (2 * np.pi), source)
    for preload, model in parsed:
        _check_damping(model, model.coefficients, _model_where(source, preload, len(parsed)))
    return cfg


# ----------------------------------------------------------------------------------------------------------
# a physical model: a passive joint, bounded motion

def _model_where(source, preload, n_models) -> str:
    return f"{source}: [model]" + (f" (preload {preload!r})" if n_models > 1 else "")


def _key(model, coefficient) -> str:
    """How a coefficient is set in a ``[model]`` table (its amplitude law, or ``coefficients.<name>``)."""
    term = next(t for t in model.terms if t.coefficient == coefficient)
    for k in model.amplitude_laws:
        if k in (term.coefficient, term.name):
            return f"amplitude_laws.{k}"
    return f"coefficients.{coefficient}"


def _check_damping(model, theta, loc, state=None) -> None:
    """Every damping coefficient >= 0: the joint dissipates energy (each damping term of the library
    does work against the motion when its coefficient is positive; a negative one feeds energy in)."""
    for t, c in zip(model.terms, theta):
        if t.kind == "damping" and c < 0 and (state is not None or _key(model, t.coefficient).startswith("coeff")):
            at = "" if state is None else (f" at the steady state of amplitude q_max = {state.q_max:.4g} "
                                           f"({state.omega / (2 * np.pi):.6g} Hz, force level {state.force_amplitude:g})")
            raise ManifestError(f"{loc} {_key(model, t.coefficient)}: the damping coefficient {t.coefficient} of "
                                f"term {t.name!r} is {c:.4g}{at}; a joint dissipates energy, so it must be >= 0 "
                                f"(negative damping feeds energy into the motion: no physical steady state)")


def _stiffness_force(model, theta, q) -> np.ndarray:
    """The restoring force at rest velocity, of the stiffness terms only."""
    theta = np.where([t.kind == "stiffness" for t in model.terms], theta, 0.0)
    with np.errstate(over="ignore", invalid="ignore"):
        return model.terms.restoring_force(q, np.zeros_like(q), theta)


def _well_edge(model, theta, q_reach) -> float | None:
    """The smallest ``|q| <= q_reach`` where the restoring force stops pointing back to rest, or None.

    Inside that distance the potential rises in both directions (a well); a steady state reaching
    beyond it is not a bounded motion of the model (the system escapes over the edge), even when
    harmonic balance finds a solution of its equations there.
    """
    u = q_reach * np.concatenate([np.logspace(-15, 0, 1500), np.linspace(0.0, 1.0, 1001)[1:]])
    u.sort()
    edge = None
    for sign in (1.0, -1.0):
        r = sign * _stiffness_force(model, theta, sign * u)
        bad = np.flatnonzero(~(r > 0))
        if bad.size:
            edge = u[bad[0]] if edge is None else min(edge, u[bad[0]])
    return edge


def _turning_terms(model, theta, q) -> str:
    """The stiffness terms pulling away from rest at ``q`` (the ones that open the well)."""
    out = []
    for t, c in zip(model.terms, theta):
        if t.kind == "stiffness" and c != 0 and np.sign(q) * c * float(t(np.array([q]), np.zeros(1))[0]) < 0:
            out.append(f"{_key(model, t.coefficient)} = {c:.4g} (term {t.name!r})")
    return ", ".join(out) or "the stiffness terms"


def _check_bounded(model, states, loc) -> None:
    """The steady states stay inside the well of the restoring force, and dissipate."""
    reaches = []
    for state in states:
        _check_damping(model, np.asarray(state.theta, float), loc, state)
        t = np.linspace(0.0, 2 * np.pi / state.omega, 256, endpoint=False)
        reaches.append(float(np.max(np.abs(state.q(t)))))
    if not reaches:
        return
    stiffness_law = any(t.kind == "stiffness" and _key(model, t.coefficient).startswith("amplitude_laws")
                        for t in model.terms)
    # the stiffness of every state is the same without a law on it: one well for the whole sweep
    groups = [[i] for i in range(len(states))] if stiffness_law else [list(range(len(states)))]
    for group in groups:
        theta = np.asarray(states[group[0]].theta, float)
        edge = _well_edge(model, theta, max(reaches[i] for i in group))
        beyond = [i for i in group if edge is not None and edge < reaches[i] * (1 - 1e-9)]
        if beyond:
            state, reach = states[beyond[0]], reaches[beyond[0]]
            raise ManifestError(
                f"{loc}: the steady state at {state.omega / (2 * np.pi):.6g} Hz, force level "
                f"{state.force_amplitude:g}, reaches |q| = {reach:.4g}; the restoring force stops pulling back to "
                f"rest by |q| = {edge:.4g} ({_turning_terms(model, theta, edge)}); no bounded motion of that size "
                f"exists (the system escapes the well): the model is not physical at this force level; lower the "
                f"force levels or the nonlinear coefficient")


def simulate_steady_states(cfg: SimulationConfig, progress=False):
    """Harmonic-balance steady states for every (preload, force level, frequency)."""
    from ..simulate.hbm import frequency_response

    out = []
    jobs = [(p, m, F) for p, m in cfg.models for F in cfg.force_levels]
    from .parallel import progress_bar

    bar = progress_bar(len(jobs), "steady states", enabled=progress)  # plain lines when stderr is no terminal
    for preload, model, F in jobs:
        loc = _model_where(cfg.source, preload, len(cfg.models))
        try:
            frf = frequency_response(model, F, cfg.omegas, n_harmonics=cfg.n_harmonics, stability=False)
        except ConvergenceError as exc:
            edge = _well_edge(model, np.asarray(model.coefficients, float), F / model.omega1 ** 2)
            if edge is None:
                raise
            raise ConvergenceError(f"{loc}: harmonic balance found no steady state at force level {F:g}; the "
                                   f"restoring force stops pulling back to rest by |q| = {edge:.4g} "
                                   f"({_turning_terms(model, model.coefficients, edge)}), below the static "
                                   f"deflection {F / model.omega1 ** 2:.4g} of that force: the model cannot hold it "
                                   f"(it escapes the well); lower the force levels or the nonlinear coefficient") \
                from exc
        _check_bounded(model, frf.states, loc)
        out.append((preload, F, frf))
        bar.update(1)
    bar.close()
    return out


def simulate_campaign(config, out_dir, progress=False) -> Path:
    """Write a campaign folder (``campaign.toml`` + ``records/NNNN.csv``) from a configuration.

    The campaign is one output set of kind ``simulate`` (:func:`jointid.io.outputset.output_set`):
    it replaces an earlier simulated campaign in ``out_dir`` as a whole (no stale records of a
    longer earlier run), and a folder holding anything else (a campaign written by hand or
    imported, results beside the records, the configuration file) is refused before any work.
    """
    from ..io.outputset import output_set

    cfg = config if isinstance(config, SimulationConfig) else load_simulation_config(config)
    inputs = () if isinstance(config, (SimulationConfig, dict)) else (config,)
    final = Path(out_dir)
    with output_set(final, kind="simulate", inputs=inputs) as out:
        _write_campaign(cfg, out, progress)
    return final


def _write_campaign(cfg: SimulationConfig, out: Path, progress=False) -> None:
    from ..simulate.synth import synthesize_record

    rng = np.random.default_rng(cfg.seed)
    entries = []
    i = 0
    for preload, F, frf in simulate_steady_states(cfg, progress):
        for state in frf.states:
            duration = cfg.periods * 2 * np.pi / state.omega
            t, Q, qdd = synthesize_record(state, cfg.fs, duration, t0=cfg.t0, noise=cfg.noise, rng=rng)
            rel = f"records/{i:04d}.csv"
            write_csv_record(out / rel, t, {"force": Q, "accel": qdd})
            entries.append(
                {
                    "file": rel,
                    "frequency_hz": state.omega / (2 * np.pi) if cfg.write_frequency else None,
                    "force_level": F,
                    "preload": preload,
                }
            )
            i += 1
    write_campaign(out, cfg.name, entries, coordinates="modal")
