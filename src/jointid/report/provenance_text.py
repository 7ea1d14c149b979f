"""The provenance of a run (``results.json`` / ``study.json`` ``provenance``) as one report line."""

from __future__ import annotations

__all__ = ["provenance_line"]


def provenance_line(p: dict | None) -> str:
    """One line of a report: ``jointid 0.1.0 (code 1a2b...), numpy ..., on host (executor, N workers), ...``."""
    if not p:
        return ""
    v = p.get("versions", {})
    libs = ", ".join(f"{k} {v[k]}" for k in ("numpy", "scipy", "dask", "distributed") if v.get(k))
    where = p.get("executor", "?")
    n = p.get("workers")
    plan = f", plan {p['plan_fingerprint']}" if p.get("plan_fingerprint") else ""
    return (f"run by jointid {v.get('jointid')} (code {p.get('code_fingerprint')}{plan}), Python {v.get('python')}, "
            f"{libs}; on {p.get('host')}, {where}" + (f" with {n} worker(s)" if n else "")
            + f"; {p.get('wall_s')} s wall, {p.get('cpu_s')} s CPU")
