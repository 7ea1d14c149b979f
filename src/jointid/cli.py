"""Command line of jointid: thin wrappers around the public API.

Exit codes: 0 success; 1 the run finished with flagged results: some records failed or were
flagged by the plausibility checks, or a model does not fit its data (``results.json``
``fit_checks``), or (identify) the model used for a preload does not hold (``adequacy``); 2 bad input (invalid arguments, manifest, configuration, record file
or output folder), checked before the work starts where it can be; 3 an unexpected internal
error; 4 incomplete: the dask cluster (its scheduler) was lost mid-run, run the same command
again (a study resumes from the campaigns done); 130 interrupted (Ctrl-C), with the previous
output set left as it was (a study says what its folder holds).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import warnings
from pathlib import Path

from .errors import ClusterLostError, JointidError, JointidWarning

EXIT_OK, EXIT_PARTIAL, EXIT_INPUT, EXIT_INTERNAL, EXIT_INCOMPLETE, EXIT_INTERRUPTED = 0, 1, 2, 3, 4, 130


def _int_in(lo, hi):
    """An argparse type: an integer from ``lo`` to ``hi``."""
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"expected an integer from {lo} to {hi}, got {value}")
        return value
    return parse


def _float_in(lo, hi):
    """An argparse type: a finite number from ``lo`` to ``hi``."""
    def parse(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not lo <= value <= hi:  # also refuses nan
            raise argparse.ArgumentTypeError(f"expected a finite number from {lo:g} to {hi:g}, got {text}")
        return value
    return parse

#: Default output folder of ``jointid example``.
EXAMPLE_OUT = Path("example-out")

EPILOG = """examples:
  jointid demo --out demo-out                # the virtual bolted-beam experiment, report.html
  jointid example --out example-out          # the seed paper's numerical example (Tables 1-3, Figs 4-6)
  jointid example --copy all                 # the example input files (simulation, import, study) into examples/
  jointid simulate config.toml --out camp    # write a simulated campaign
  jointid identify camp --out results        # identify it: results.json, CSV tables, PNG figures
  jointid backbone results                   # omega(a), zeta(a) of a saved result, into results-backbone/
  jointid predict results --force-levels 1,2,3.5 --out pred   # the identified model at new force levels
  jointid study plan.toml --out study --jobs 2   # Monte Carlo study: bias, RMSE, std(z), coverage
  jointid modal structure.toml --out modal   # FE modes, updating report, mode-shape plots
  jointid modal structure.toml --frf random.uff --response accel_42   # + modal fit of H1, trusted peaks
"""


def _add_parallel_options(p, what):
    p.add_argument("--jobs", type=int, default=1,
                   help=f"worker processes for the {what}: 1 runs them in this process, N > 1 on a local dask "
                        "cluster, 0 one per core (default: %(default)s; results do not depend on it)")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help=f"run the {what} on an existing dask cluster, e.g. tcp://10.0.0.5:8786 (see docs/scale-out.md)")


#: ``identify --figures``: which figures are drawn (see :func:`jointid.report.output.campaign_figures`).
FIGURE_LEVELS = ("none", "summary", "all")


def _add_identify_options(p):
    p.add_argument("--terms", default="q + -q^3 + q'",
                   help="restoring-force terms, e.g. \"q + -q^3 + q'\" or eq22, or auto: the model each preload's "
                        "data select (polynomial, amplitude-law and hysteretic candidate families ranked by how well "
                        "they predict each force level left out; docs/method.md) (default: %(default)s)")
    p.add_argument("--harmonics", type=_int_in(1, 200), default=5,
                   help="harmonics fitted to the acceleration (default: %(default)s)")
    p.add_argument("--damping-order", type=_int_in(0, 10), default=2, help="order of c(q_max) (default: %(default)s)")
    p.add_argument("--weighting", choices=("noise", "none"), default="noise",
                   help="record weights in the pooled regression (default: %(default)s)")
    p.add_argument("--force-gain", choices=("known", "unknown"), default="known",
                   help="'unknown' when the force column is e.g. a shaker voltage: the gain is identified "
                        "with the inertia term and omega1, k3, c are gain-free (default: %(default)s)")
    _add_parallel_options(p, "records")
    p.add_argument("--trust-frequency", action="store_true",
                   help="use the manifest's frequency_hz as it is (by default it is checked on the force)")
    p.add_argument("--keep-flagged", action="store_true",
                   help="keep records flagged by the plausibility checks in the pooled fits (default: left out)")
    p.add_argument("--channel-delay", default=None, metavar="estimate|SECONDS",
                   help="delay of the response channel behind the force (voltage) channel: 'estimate' (from the "
                        "dwells' damping, with a standard error) or a known value in seconds (default: none)")
    p.add_argument("--no-reprediction", action="store_true",
                   help="skip the harmonic-balance re-prediction of the measured FRFs")
    p.add_argument("--figures", choices=FIGURE_LEVELS, default="summary",
                   help="PNG figures in figures/ and report.html: 'summary' the laws, re-prediction, model "
                        "selection and backbones of each preload; 'all' also the per-record parameters and the "
                        "hysteresis loops of every group (slower: about a second per figure); 'none' (default: "
                        "%(default)s)")
    p.add_argument("--no-figures", action="store_true", help="no PNG figures (the same as --figures none)")
    p.add_argument("--quiet", action="store_true",
                   help="no progress and no report on stdout (failed and flagged records are still listed)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jointid",
        description="Identify nonlinear bolted-joint parameters from vibration tests by force-state mapping.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"jointid {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("identify", help="identify a campaign folder", epilog="example: jointid identify camp --out res",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("campaign", type=Path, help="campaign folder with campaign.toml")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    _add_identify_options(p)

    p = sub.add_parser("simulate", help="write a simulated campaign from a TOML configuration",
                       epilog="example: jointid simulate config.toml --out camp")
    p.add_argument("config", type=Path, help="simulation configuration (see docs/formats.md)")
    p.add_argument("--out", type=Path, required=True, help="campaign folder to write")
    p.add_argument("--quiet", action="store_true", help="no progress and no closing line on stdout")

    p = sub.add_parser("demo", help="the virtual bolted-beam experiment end to end, with an HTML report",
                       epilog="example: jointid demo --out demo-out")
    p.add_argument("--out", type=Path, default=Path("demo-out"), help="output folder (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the rig's excitation and noise (default: 0)")
    p.add_argument("--no-figures", action="store_true", help="only results.json (no figures, no report.html)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")

    p = sub.add_parser("import", help="turn lab exports (UFF58, MAT/Test.Lab, HDF5, CSV) into a campaign folder",
                       epilog="example: jointid import description.toml --out campaign  (format: jointid.io.importer)")
    p.add_argument("description", type=Path, help="import description (TOML)")
    p.add_argument("--out", type=Path, required=True, help="campaign folder to write")

    p = sub.add_parser("public-data", help="the worked examples on the public data sets in ../shared/data",
                       epilog="example: jointid public-data --out public-out --only silverbox")
    p.add_argument("--out", type=Path, help="folder for the figures and results.json")
    p.add_argument("--only", choices=("silverbox", "benchmark", "unesp", "f16"), action="append",
                   help="run only these examples (repeatable)")

    p = sub.add_parser("example", help="the seed paper's numerical example: Tables 1-3 and Figs 4-6; "
                                       "--list / --copy: the example input files that come with jointid",
                       epilog="examples:\n  jointid example --out example-out     # the paper's numerical example\n"
                              "  jointid example --list                 # the example input files\n"
                              "  jointid example --copy all             # copied to ./examples/ (never overwritten)",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    files = p.add_mutually_exclusive_group()
    files.add_argument("--out", type=Path, default=None,
                       help=f"output folder of the numerical example (default: {EXAMPLE_OUT})")
    files.add_argument("--list", action="store_true",
                       help="list the example input files (simulation, import, study) and stop")
    files.add_argument("--copy", nargs="+", metavar="NAME",
                       help="copy these example files ('all': every one) into --to and stop; an existing file is "
                            "not replaced (exit 2)")
    p.add_argument("--to", type=Path, default=Path("examples"),
                   help="folder that --copy writes to (default: %(default)s, as in the commands of the README)")
    p.add_argument("--frequencies", type=_int_in(2, 10000), default=41, help="number of excitation frequencies (default: 41)")
    p.add_argument("--no-figures", action="store_true", help="no PNG figures and no figures in report.html")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p = sub.add_parser("modal", help="FE modes, shapes and updating report of a structure description",
                       epilog="example: jointid modal campaign.toml --out modal-out --frf random.csv --response accel_42",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("structure", type=Path, help="TOML file with a [structure] table (a campaign.toml works)")
    p.add_argument("--out", type=Path, default=Path("modal-out"),
                   help="folder for modal.json and the mode-shape / updating / FRF figures (default: %(default)s)")
    p.add_argument("--frf", type=Path, help="a random-excitation record (CSV: time, force, responses) for H1 and a modal fit")
    p.add_argument("--response", default=None, help="response column of --frf (default: the first sensor)")
    p.add_argument("--modes", type=_int_in(1, 50), default=3, help="modes fitted in the FRF (default: %(default)s)")
    p.add_argument("--bands", default=None,
                   help="explicit fit bands in Hz, one per mode, e.g. \"24-29,140-175\" (default: automatic picking)")
    p.add_argument("--f-range", nargs=2, type=_float_in(0.0, 1e9), metavar=("LO", "HI"), default=None,
                   help="search peaks between LO and HI Hz (default: where the force spectrum excites the structure)")
    p.add_argument("--order", type=_int_in(0, 64), default=8,
                   help="highest model order of the pole stabilisation check (0: no check; default: %(default)s)")
    p.add_argument("--nperseg", type=_int_in(16, 2**31), default=None,
                   help="Welch segment length of H1 in samples (default: an eighth of the record)")
    p.add_argument("--min-coherence", type=_float_in(0.0, 1.0), default=0.8,
                   help="lowest median coherence of a trusted peak's band (default: %(default)s)")

    p = sub.add_parser("backbone", help="draw omega(a), zeta(a) of a saved identification (results.json)",
                       epilog="example: jointid backbone results --out backbone-out")
    p.add_argument("results", type=Path, help="results folder written by jointid identify, or its results.json")
    p.add_argument("--out", type=Path, default=None,
                   help="folder for backbone_<preload>.png (default: RESULTS-backbone beside the results folder)")
    p.add_argument("--harmonics", type=_int_in(1, 50), default=1,
                   help="harmonics of the model backbone (1: first-harmonic balance; default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no table on stdout")

    p = sub.add_parser("predict", help="predict the response at new force levels with a saved identification's model",
                       epilog="example: jointid predict results --force-levels 1,2,3.5 --out predict-out")
    p.add_argument("results", type=Path, help="results folder written by jointid identify, or its results.json, "
                   "or a structure model file MODEL.toml (docs/formats.md)")
    p.add_argument("--force-levels", required=True, metavar="F1,F2,...",
                   help="force levels in the campaign's force_level units, separated by commas")
    p.add_argument("--out", type=Path, required=True, help="output folder (results.json, report.txt, report.html, figures/)")
    p.add_argument("--frequency-range", nargs=2, type=_float_in(0.0, 1e9), metavar=("LO", "HI"), default=None,
                   help="band of the curves in Hz (default: the measured band, widened until the peak is inside)")
    p.add_argument("--harmonics", type=_int_in(1, 50), default=None,
                   help="harmonics of the harmonic balance (default: 5; for MODEL.toml its [predict] "
                   "n_harmonics when it has one)")
    p.add_argument("--no-uncertainty", action="store_true",
                   help="skip the standard errors of the peaks (two more solutions per model parameter)")
    p.add_argument("--time-check", type=_int_in(0, 50), default=None, metavar="N",
                   help="MODEL.toml: time-integrate the peaks of the N largest force levels (default: up to 3; 0: none)")
    p.add_argument("--quiet", action="store_true", help="no progress and no table on stdout")

    p = sub.add_parser("update", help="fit a structure model's joint law to measured first harmonics and/or "
                       "backbones (docs/formats.md)",
                       epilog="example: jointid update lap_joint.toml measured.csv backbone.csv --out upd")
    p.add_argument("model", type=Path, help="structure model file MODEL.toml")
    p.add_argument("measured", type=Path, nargs="+", help="measured files, CSV, each recognised by its header: "
                   "first harmonics (force_level, frequency_hz, dof, a1, b1, se) or a backbone (dof, amplitude, "
                   "frequency_hz, se_frequency_hz, damping_ratio, se_damping_ratio[, mode])")
    p.add_argument("--out", type=Path, required=True, help="output folder (results.json, report.txt, figures/)")
    p.add_argument("--joint", default=None, help="name of the joint element to update (default: the first)")
    p.add_argument("--parameters", default=None, metavar="P1,P2,...",
                   help="law parameters to fit (default: all of the law's parameters)")
    p.add_argument("--harmonics", type=_int_in(1, 50), default=9, help="harmonics of the harmonic balance "
                   "(default: %(default)s; 5 biased a Jenkins fit by 1.4 se)")
    p.add_argument("--no-heldout", action="store_true", help="skip the leave-one-level-out check")
    p.add_argument("--quiet", action="store_true", help="no report on stdout")

    p = sub.add_parser("study", help="Monte Carlo study: simulated campaigns identified and compared with the truth",
                       epilog="example: jointid study plan.toml --out study --jobs 2  (plan format: jointid.app.study)")
    p.add_argument("plan", type=Path, help="study plan (TOML: a simulation configuration with [study], [vary], [grid])")
    p.add_argument("--out", type=Path, required=True,
                   help="output folder; campaigns already in its campaigns.jsonl are not run again")
    _add_parallel_options(p, "campaigns")
    p.add_argument("--no-report", action="store_true", help="skip report.html")
    p.add_argument("--allow-version-mix", action="store_true",
                   help="resume campaigns made by another jointid version (refused by default)")
    p.add_argument("--quiet", action="store_true", help="no progress and no table on stdout")
    return parser


def _modal(args) -> int:
    from .app.modal_workflow import modal_workflow, write_modal

    run = modal_workflow(args.structure, frf=args.frf, response=args.response, modes=args.modes, bands=args.bands,
                         f_range=args.f_range, order=args.order, nperseg=args.nperseg,
                         min_coherence=args.min_coherence, echo=print)
    if args.out is not None:  # (default modal-out)
        write_modal(run, args.out)
        print(f"\nwritten to {args.out}")
    return EXIT_OK


def _channel_delay(text):
    """``--channel-delay``: None, "estimate" or a finite number of seconds."""
    if text is None or text == "estimate":
        return text
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not math.isfinite(value):
        from .errors import IdentificationError

        raise IdentificationError(f"--channel-delay: expected 'estimate' or a delay in seconds, got {text!r}")
    return value


class _Stages:
    """One line per stage of a command on stderr, with the seconds it took (nothing when quiet)."""

    def __init__(self, command, quiet=False):
        import time

        self._clock, self.command, self.quiet = time.perf_counter, command, quiet
        self.t0 = self.t = self._clock()

    def __call__(self, text):
        now = self._clock()
        if not self.quiet:
            print(f"jointid {self.command}: {text} [{now - self.t:.1f} s, {now - self.t0:.1f} s in all]",
                  file=sys.stderr, flush=True)
        self.t = now


def _identify(args) -> int:
    stage = _Stages("identify", args.quiet)
    from .report.output import write_results
    from .app.workflow import identify_campaign

    stage(f"modules loaded; reading and reducing the records of {args.campaign}")
    result = identify_campaign(
        args.campaign, terms=args.terms, n_harmonics=args.harmonics, damping_order=args.damping_order,
        weighting=args.weighting, force_gain=args.force_gain, refine_frequency=not args.trust_frequency, jobs=args.jobs,
        scheduler=args.scheduler, progress=not args.quiet, keep_flagged=args.keep_flagged,
        channel_delay=_channel_delay(args.channel_delay), repredict=not args.no_reprediction,
    )
    n_groups = sum(g.pooled is not None for g in result.groups)
    stage(result.stage_line() if hasattr(result, "stage_line") else  # a first-harmonic campaign says its own
          f"identified {len(result.records)} records, {n_groups} groups, {len(result.models)} preload model(s): "
          "pooled fits, laws, adequacy, " + ("" if args.no_reprediction else "re-prediction by harmonic balance, ")
          + "backbones")
    level = "none" if args.no_figures else args.figures
    paths = write_results(result, args.out, figures={"none": False, "summary": "summary", "all": True}[level])
    try:
        n_figures = len(paths.get("figures") or [])
        drawn = {"none": "no figures (--figures summary|all draws them)",
                 "summary": f"{n_figures} figures of the preloads (--figures all adds each group's)",
                 "all": f"{n_figures} figures"}[level]
        stage(f"written: results.json, CSV tables, report.txt, report.html, {drawn}")
        return _identify_console(args, result)
    except KeyboardInterrupt:  # the new set is already in place: the usual message would be false
        raise KeyboardInterrupt(f"the new output set was complete and is in {args.out}") from None


def _identify_console(args, result) -> int:
    """What identify prints once its output set is written, and its exit status."""
    from .report.output import flagged_lines
    from .report.summary import console_lines, error_lines

    summary = result.summary()
    if not args.quiet:
        print(result.report())
        print("\n" + "\n".join(console_lines(summary)))
        print(f"\nresults written to {args.out}")
    else:  # --quiet never hides failures: one line per kind of error, with a count
        for line in error_lines(summary):
            print(f"failed: {line}", file=sys.stderr)
    for line in flagged_lines(result):  # also when quiet: a flagged record needs a look
        print(line, file=sys.stderr)
    from .app.fit_checks import misfit_lines

    misfit = misfit_lines(summary)
    for line in misfit:  # also when quiet: a model that does not fit needs a look
        print(line, file=sys.stderr)
    from .app.record_problems import problem_lines

    broadband = problem_lines(result)  # broadband and ring-down records flagged or not usable
    for line in broadband:
        print(line, file=sys.stderr)
    # the model used for a preload (the selected one under --terms auto) does not hold: also when quiet
    inadequate = [f"preload {a.get('preload')}: the {a.get('model')} model used does NOT hold: {a.get('verdict')}"
                  for a in summary.get("adequacy") or [] if isinstance(a, dict) and a.get("adequate") is False]
    for line in inadequate:
        print(line, file=sys.stderr)
    return EXIT_PARTIAL if result.failed or result.flagged or broadband or misfit or inadequate else EXIT_OK


def _study(args) -> int:
    from .app.study import load_study_plan, run_study

    plan = load_study_plan(args.plan)
    res = run_study(plan, args.out, jobs=args.jobs, scheduler=args.scheduler, progress=not args.quiet,
                    report=not args.no_report, allow_version_mix=args.allow_version_mix)
    if not args.quiet:
        print(res.report())
        print(f"\n{res.n_run} campaigns run, {len(res.campaigns) - res.n_run} already in {args.out}; "
              f"results written to {args.out}")
    elif res.failed:  # quiet: the failures only (the first ten, as the report lists them)
        print(f"jointid study: {len(res.failed)} of {len(res.campaigns)} campaigns failed", file=sys.stderr)
        for c in res.failed[:10]:
            print(f"  {c['error']}", file=sys.stderr)
    return EXIT_PARTIAL if res.failed else EXIT_OK


def _simulate(args) -> int:
    from .app.synthesis import simulate_campaign

    out = simulate_campaign(args.config, args.out, progress=not args.quiet)
    if not args.quiet:
        print(f"campaign written to {out}")
    return EXIT_OK


def _demo(args) -> int:
    from .app.demo import run_demo

    res = run_demo(args.out, progress=not args.quiet, seed=args.seed, figures=not args.no_figures)
    print(res.report())
    # exit 1 when an acceptance check of the virtual experiment failed
    return EXIT_OK if all(res.checks["passed"].values()) else EXIT_PARTIAL


def _import(args) -> int:
    from .io.importer import import_campaign
    from .modal.structure import Structure

    # the [structure] tables are checked (as identify reads them) before any file is read
    res = import_campaign(args.description, args.out, check_structure=lambda t, src: Structure.from_mapping(t, src))
    print(res.report())
    return EXIT_PARTIAL if res.failed else EXIT_OK


def _example_files(args) -> int:
    """``jointid example --list`` / ``--copy NAME... [--to DIR]``."""
    from .examples import copy_examples, example_files

    if args.list:
        files = example_files()
        width = max(map(len, files))
        for name, about in files.items():
            print(f"{name:<{width}}  {about}")
        print(f"\njointid example --copy NAME|all [--to DIR] copies them (default folder: {args.to})")
        return EXIT_OK
    for path in copy_examples(args.copy, args.to):
        print(f"copied {path}")
    return EXIT_OK


def _example(args) -> int:
    if args.list or args.copy:
        return _example_files(args)
    from .app.paper_example import run_paper_example

    res = run_paper_example(args.out, n_frequencies=args.frequencies, figures=not args.no_figures,
                            progress=not args.quiet)
    print(res.report())
    print(f"\ncampaign, results, tables and figures written to {args.out}")
    return EXIT_PARTIAL if res.eq21.failed else EXIT_OK


def _results_file(path: Path) -> Path:
    """``backbone RESULTS``: a results folder (its results.json) or the results.json itself."""
    from .errors import RecordFileNotFoundError

    file = path / "results.json" if path.is_dir() else path
    if not file.is_file():
        what = f"{path}: a folder without results.json" if path.is_dir() else f"{path}: no such file or folder"
        raise RecordFileNotFoundError(f"{what}; give the output folder of jointid identify or its results.json")
    return file


def _resolve_outputs(args) -> None:
    """Defaults that depend on other arguments, set before the output folder is checked."""
    if args.command == "example" and args.out is None and not (args.list or args.copy):
        args.out = EXAMPLE_OUT
    elif args.command == "backbone":
        args.results = _results_file(args.results)
        if args.out is None:  # beside the results folder, never inside it (that folder is one run's set)
            folder = args.results.parent
            folder = folder.resolve() if folder.name in ("", ".", "..") else folder
            args.out = folder.parent / f"{folder.name}-backbone"


def _backbone(args) -> int:
    from .app.backbones import backbones_from_results, write_backbone_figures

    bb = backbones_from_results(args.results, n_harmonics=args.harmonics)
    paths = write_backbone_figures(bb, args.out, inputs=(args.results.parent,))
    problems = [f"preload {p.preload}: {k}: {e}" for p in bb.preloads for k, e in p.errors.items()]
    if not args.quiet:
        print(bb.report())
        print(f"\n{len(paths)} figure(s) and backbones.json written to {args.out}")
    else:
        for line in problems:
            print(f"jointid backbone: {line}", file=sys.stderr)
    return EXIT_PARTIAL if problems else EXIT_OK  # a model without a backbone, or one that does not hold


def _predict(args) -> int:
    from .app.predict import load_results, predict_from_results, write_predictions
    from .io.outputset import check_output_folder

    if args.results.suffix.lower() == ".toml":  # a structure model file (docs/formats.md)
        return _predict_structure(args)

    _, file = load_results(args.results)  # a bad file: one line, before any work
    check_output_folder(args.out, "predict", inputs=(file.parent,))
    progress = None if args.quiet else (lambda line: print(f"jointid predict: {line}", file=sys.stderr, flush=True))
    res = predict_from_results(file, args.force_levels, frequency_range=args.frequency_range,
                               n_harmonics=5 if args.harmonics is None else args.harmonics, uncertainty=not args.no_uncertainty, progress=progress)
    write_predictions(res, args.out, inputs=(file.parent,))
    if not args.quiet:
        print(res.report())
        print(f"\nresults written to {args.out}")
    else:
        for line in res.lines():
            if "EXTRAPOLATED" in line or "FAILED" in line or "no peak" in line:
                print(line, file=sys.stderr)
    return EXIT_PARTIAL if res.failed else EXIT_OK


def _predict_structure(args) -> int:
    from .app.predict import parse_force_levels
    from .app.structure_predict import predict_structure, write_structure_predictions
    from .io.outputset import check_output_folder

    levels = parse_force_levels(args.force_levels)
    check_output_folder(args.out, "predict", inputs=(args.results.parent,))
    progress = None if args.quiet else (lambda line: print(f"jointid predict: {line}", file=sys.stderr, flush=True))
    res = predict_structure(args.results, force_levels=levels, frequency_range=args.frequency_range,
                            n_harmonics=args.harmonics, progress=progress,  # None: the file's, else 5
                            time_check=args.time_check)
    write_structure_predictions(res, args.out, inputs=(args.results.parent,))
    if not args.quiet:
        print(res.report())
        print(f"\nresults written to {args.out}")
    else:  # what makes the prediction unsure, even when quiet
        for line in res.lines():
            if "FAILED" in line or "WARNING" in line or "no peak" in line:
                print(f"jointid predict: {line}", file=sys.stderr)
    return EXIT_PARTIAL if res.failed else EXIT_OK


def _update(args) -> int:
    from .app.update_joint import read_measured, update_joint, write_update

    meas, bbs = read_measured(args.measured)  # a bad file: one line, before any work
    pars = None if args.parameters is None else [s.strip() for s in args.parameters.split(",") if s.strip()]
    res = update_joint(args.model, ([meas] if meas is not None else []) + bbs, joint=args.joint, parameters=pars,
                       n_harmonics=args.harmonics, heldout=not args.no_heldout)
    write_update(res, args.out, inputs=(args.model.parent, *(m.parent for m in args.measured)))
    if not args.quiet:
        print(res.report())
        print(f"\nresults written to {args.out}")
    elif res.flagged:
        for line in res.warnings:
            print(f"jointid update: {line}", file=sys.stderr)
    return EXIT_PARTIAL if res.flagged else EXIT_OK  # an inadequate law, a unit slip: a status a script can see


COMMANDS = {"demo": _demo, "import": _import, "identify": _identify, "simulate": _simulate, "example": _example, "modal": _modal,
            "study": _study, "backbone": _backbone, "predict": _predict,
            "update": _update}


def _interrupted(exc) -> bool:
    """True when ``exc`` was caused by a KeyboardInterrupt (its ``__cause__`` / ``__context__`` chain)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["public-data"]:  # its options belong to the examples' own parser
        from .app.public_data import main as examples_main

        return examples_main(argv[1:])
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        # jointid warnings are recorded per record in results.json; do not flood the terminal
        if getattr(args, "quiet", False) or args.command in ("identify", "example", "demo"):
            warnings.simplefilter("ignore", JointidWarning)
        try:
            if getattr(args, "scheduler", None) is not None:  # a bad address: one line, before any folder is made
                from .app.parallel import check_scheduler

                check_scheduler(args.scheduler)
            _resolve_outputs(args)
            if getattr(args, "out", None) is not None:  # refuse an unwritable --out before the work
                from .io.outputset import check_command_output

                check_command_output(args.command, args.out, [getattr(args, k, None) for k in ("campaign", "plan", "description")])
            return COMMANDS[args.command](args)
        except KeyboardInterrupt as exc:  # a study's says what its folder holds
            print(f"jointid {args.command}: interrupted; {str(exc) or 'earlier results are left as they were'}", file=sys.stderr)
            return EXIT_INTERRUPTED
        except ClusterLostError as exc:
            print(f"jointid {args.command}: incomplete: {exc}", file=sys.stderr)
            return EXIT_INCOMPLETE
        except JointidError as exc:
            print(f"jointid {args.command}: error: {exc}", file=sys.stderr)
            return EXIT_INPUT
        except Exception as exc:  # an unexpected failure: say so, with the traceback, and a distinct code
            if _interrupted(exc):  # a Ctrl-C that Python wrapped (e.g. raised inside a class body's __set_name__)
                print(f"jointid {args.command}: interrupted; earlier results are left as they were", file=sys.stderr)
                return EXIT_INTERRUPTED
            import traceback

            traceback.print_exc()
            print(f"jointid {args.command}: internal error (please report it with the traceback above)", file=sys.stderr)
            return EXIT_INTERNAL


def _redeliver_lost_interrupts() -> None:
    """Make a Ctrl-C that lands where Python cannot raise it reach the command all the same.

    A KeyboardInterrupt raised inside a weakref callback or a finaliser (run by the garbage
    collector at an arbitrary point) cannot propagate: Python hands it to ``sys.unraisablehook``,
    which prints "Exception ignored in ..." with a traceback, and the interrupt is lost (the
    run goes on). This hook delivers it again to the main thread instead: a SIGINT made pending
    a moment later from another thread (made pending at once, it would be raised inside the
    hook itself), raised at the next point where the main thread checks for signals. Any other
    unraisable exception goes to the previous hook.
    """
    import _thread
    import threading

    previous = sys.unraisablehook

    def hook(unraisable):
        if issubclass(unraisable.exc_type, KeyboardInterrupt):
            timer = threading.Timer(0.01, _thread.interrupt_main, (signal.SIGINT,))
            timer.daemon = True
            timer.start()
            return
        previous(unraisable)

    sys.unraisablehook = hook


def entry() -> int:
    """The console command: :func:`main`, then a Ctrl-C during the interpreter's teardown is ignored.

    Once ``main`` has returned the work and its message are complete; a SIGINT arriving while
    Python shuts down (atexit handlers, module teardown, where the default action kills the
    process) would otherwise end it by the signal, or with a traceback, instead of its exit status.
    A Ctrl-C that lands in a garbage-collector callback is delivered again
    (:func:`_redeliver_lost_interrupts`).
    """
    _redeliver_lost_interrupts()
    try:
        code = main()
    except KeyboardInterrupt:  # outside a command's own handling (its arguments, or after it returned)
        print("jointid: interrupted", file=sys.stderr)
        code = EXIT_INTERRUPTED
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(entry())
