"""jointid: identification of nonlinear bolted-joint parameters by force-state mapping.

Quick start
-----------
>>> import jointid                                              # doctest: +SKIP
>>> result = jointid.identify_campaign("campaign")             # doctest: +SKIP
>>> print(result.report())                                     # doctest: +SKIP

A campaign is a folder with ``campaign.toml`` and its records (``docs/formats.md``);
``jointid example --copy all`` then ``jointid simulate examples/noisy_softening.toml --out
campaign`` writes one (the example files come with the package: :func:`example_files`).

The data flow is the package layout: ``io`` (records, campaigns) -> ``signal`` (state
signals) -> ``modal`` (structure, modal coordinates) -> ``identify`` (force-state
mapping, laws, uncertainty) -> ``simulate`` (harmonic balance, time integration) ->
``rig`` (virtual test rig) -> ``report`` (tables, figures, HTML); ``app`` holds the
workflows a command runs and :mod:`jointid.cli` is the command line.
"""

__version__ = "0.1.0"

#: Public names and the module each comes from; a module is imported on first use of one of
#: its names, so that ``import jointid`` stays light (numpy, scipy and matplotlib load later).
_LAZY = {
    # a campaign folder -> identified model, laws, reports (the main entry point)
    "identify_campaign": "jointid.app.workflow",
    "IdentifySettings": "jointid.app.workflow",
    "CampaignResult": "jointid.app.workflow",
    "write_results": "jointid.report.output",
    # campaigns: read, simulate, import
    "load_campaign": "jointid.io.campaign",
    "load_simulation_config": "jointid.app.synthesis",
    "simulate_campaign": "jointid.app.synthesis",
    "import_campaign": "jointid.io.importer",
    # the steps one by one
    "steady_state_signals": "jointid.signal.harmonics",
    "ForceStateMapping": "jointid.identify.fsm",
    "PooledForceStateMapping": "jointid.identify.fsm",
    "seed_model": "jointid.simulate.model",
    "SingleModeModel": "jointid.simulate.model",
    "frequency_response": "jointid.simulate.hbm",
    # saved results, the demo, the paper's example, Monte Carlo studies
    "backbones_from_results": "jointid.app.backbones",
    "run_demo": "jointid.app.demo",
    "run_paper_example": "jointid.app.paper_example",
    "load_study_plan": "jointid.app.study",
    "run_study": "jointid.app.study",
    "example_files": "jointid.examples",
    "copy_examples": "jointid.examples",
    # the project's exceptions and warnings (also importable from jointid.errors)
    "JointidError": "jointid.errors",
    "ManifestError": "jointid.errors",
    "RecordError": "jointid.errors",
    "IdentificationError": "jointid.errors",
    "JointidWarning": "jointid.errors",
}

__all__ = ["__version__", *_LAZY]


def __getattr__(name):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'jointid' has no attribute {name!r}")
    from importlib import import_module

    value = getattr(import_module(module), name)
    globals()[name] = value  # the next look-up is a plain attribute
    return value


def __dir__():
    # tab completion lists the public names before any of them is imported
    return sorted(set(globals()) | set(__all__))
