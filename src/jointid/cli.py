"""Command line of jointid: thin wrappers around the public API.

Exit codes: 0 success; 1 the run finished but some records failed; 2 bad input
(invalid arguments, manifest or configuration); 3 an unexpected internal error.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from .errors import JointidError, JointidWarning

EXIT_OK, EXIT_PARTIAL, EXIT_INPUT, EXIT_INTERNAL = 0, 1, 2, 3

EPILOG = """examples:
  jointid example --out example-out          # the seed paper's numerical example (Tables 1-3, Figs 4-6)
  jointid simulate config.toml --out camp    # write a simulated campaign
  jointid identify camp --out results        # identify it: results.json, CSV tables, PNG figures
"""


def _add_identify_options(p):
    p.add_argument("--terms", default="q + -q^3 + q'",
                   help="restoring-force terms, e.g. \"q + -q^3 + q'\" or eq22 (default: %(default)s)")
    p.add_argument("--harmonics", type=int, default=5, help="harmonics fitted to the acceleration (default: %(default)s)")
    p.add_argument("--damping-order", type=int, default=2, help="order of c(q_max) (default: %(default)s)")
    p.add_argument("--weighting", choices=("noise", "none"), default="noise",
                   help="record weights in the pooled regression (default: %(default)s)")
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no report on stdout")


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
    p.add_argument("config", type=Path, help="simulation configuration (see jointid.synthesis)")
    p.add_argument("--out", type=Path, required=True, help="campaign folder to write")
    p.add_argument("--quiet", action="store_true")

    p = sub.add_parser("example", help="the seed paper's numerical example: Tables 1-3 and Figs 4-6",
                       epilog="example: jointid example --out example-out")
    p.add_argument("--out", type=Path, default=Path("example-out"), help="output folder (default: %(default)s)")
    p.add_argument("--frequencies", type=int, default=41, help="number of excitation frequencies (default: 41)")
    p.add_argument("--no-figures", action="store_true")
    p.add_argument("--quiet", action="store_true")
    return parser


def _identify(args) -> int:
    from .report.output import write_results
    from .workflow import identify_campaign

    result = identify_campaign(
        args.campaign, terms=args.terms, n_harmonics=args.harmonics, damping_order=args.damping_order,
        weighting=args.weighting, progress=not args.quiet,
    )
    write_results(result, args.out, figures=not args.no_figures)
    if not args.quiet:
        print(result.report())
        print(f"\nresults written to {args.out}")
    return EXIT_PARTIAL if result.failed else EXIT_OK


def _simulate(args) -> int:
    from .synthesis import simulate_campaign

    out = simulate_campaign(args.config, args.out, progress=not args.quiet)
    if not args.quiet:
        print(f"campaign written to {out}")
    return EXIT_OK


def _example(args) -> int:
    from .examples import run_paper_example

    res = run_paper_example(args.out, n_frequencies=args.frequencies, figures=not args.no_figures,
                            progress=not args.quiet)
    print(res.report())
    print(f"\ncampaign, results, tables and figures written to {args.out}")
    return EXIT_PARTIAL if res.eq21.failed else EXIT_OK


COMMANDS = {"identify": _identify, "simulate": _simulate, "example": _example}


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        # jointid warnings are recorded per record in results.json; do not flood the terminal
        if getattr(args, "quiet", False) or args.command in ("identify", "example"):
            warnings.simplefilter("ignore", JointidWarning)
        try:
            return COMMANDS[args.command](args)
        except JointidError as exc:
            print(f"jointid {args.command}: error: {exc}", file=sys.stderr)
            return EXIT_INPUT


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
