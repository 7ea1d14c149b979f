"""jointid: identification of nonlinear bolted-joint parameters by force-state mapping.

Quick start
-----------
>>> import jointid                                              # doctest: +SKIP
>>> result = jointid.identify_campaign("campaign")             # doctest: +SKIP
>>> print(result.report())                                     # doctest: +SKIP

A campaign is a folder with ``campaign.toml`` and its records (``docs/formats.md``);
``jointid simulate examples/noisy_softening.toml --out campaign`` writes one.

The data flow is the package layout: ``io`` (records, campaigns) -> ``signal`` (state
signals) -> ``modal`` (structure, modal coordinates) -> ``identify`` (force-state
mapping, laws, uncertainty) -> ``simulate`` (harmonic balance, time integration) ->
``rig`` (virtual test rig) -> ``report`` (tables, figures, HTML); ``app`` holds the
workflows a command runs and :mod:`jointid.cli` is the command line.
"""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__", "identify_campaign", "IdentifySettings"]


def __getattr__(name):
    # the application layer is imported on first use, so that ``import jointid`` stays light
    if name in ("identify_campaign", "IdentifySettings"):
        from .app import workflow

        return getattr(workflow, name)
    raise AttributeError(f"module 'jointid' has no attribute {name!r}")
